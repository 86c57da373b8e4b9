"""What every simulated plant shows the same way: the World message, the camera's view, the image.

The kinematic :class:`~robot_daemon.plant.world.SimWorld` and the MuJoCo
:class:`~robot_daemon.plant.physics.mujoco_world.MujocoWorld` differ in how the body and ball
move; what they publish and render from that state is one piece of code, here. A plant subclasses
:class:`WorldViews`, calls its constructor first (which makes the settings, the lock, the
simulated time and the camera everything here reads: nothing is declared for a subclass to set)
and says where things are (:meth:`_robot`, :meth:`_ball_now`, :meth:`_camera_pose`), under
``self.lock``; it advances ``self.time``.
"""

from __future__ import annotations

import math
import threading
import time
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any

import numpy as np

from robot_daemon.plant.ball import BallState
from robot_daemon.plant.camera_model import CameraPose
from robot_daemon.plant.world_settings import WorldSettings
from schemas.messages import World

if TYPE_CHECKING:
    from robot_daemon.plant.render import BallView, Renderer


class WorldViews(ABC):
    def __init__(self, settings: WorldSettings, seed: int | None) -> None:
        self.settings = settings
        self.lock = threading.RLock()
        self.time = 0.0  # simulated seconds, advanced by the plant
        # Made at the first frame (its own generator, seeded here, draws the same from there): a
        # world nobody watches (`darwin up --camera none`, most simulated robots) never loads it.
        self._seed = seed
        self._renderer: Renderer | None = None
        self._render_lock = threading.Lock()
        self.frames_rendered = 0  # frames served to the camera source

    # -- what a plant says (called under ``self.lock``) ----------------------------------------
    @abstractmethod
    def _robot(self) -> tuple[float, float, float, str]:
        """(x, y, heading (rad), fallen) of the body on the field."""

    @abstractmethod
    def _ball_now(self) -> BallState | None:
        """The ball as it is now, None without one."""

    @abstractmethod
    def _camera_pose(self) -> CameraPose:
        """Where the head camera is and where it looks (the renderer's axes)."""

    # -- what it shows ---------------------------------------------------------------------------
    def snapshot(self) -> World:
        """The World message (field frame, metres, radians)."""
        with self.lock:
            x, y, yaw, fallen = self._robot()
            b = self._ball_now()
            ball: dict[str, Any] = (
                {"x": float(b.x), "y": float(b.y), "vx": float(b.vx), "vy": float(b.vy)}
                if b is not None
                else {}
            )
            return World(
                robot={"x": float(x), "y": float(y), "yaw": float(yaw)},
                ball=ball,
                fallen=fallen,
                sim_time=self.time,
                stamp=time.time(),
            )

    def camera_view(self) -> tuple[CameraPose, BallView | None]:
        from robot_daemon.plant.render import BallView

        with self.lock:
            pose = self._camera_pose()
            b = self._ball_now()
            s = self.settings.ball
            return pose, BallView(b.x, b.y, s.radius, s.color) if b is not None else None

    def render(self) -> np.ndarray:
        """The camera image (BGR, uint8) of the world as it is now."""
        pose, ball = self.camera_view()
        with self._render_lock:
            return self.renderer().render(pose, ball)

    def renderer(self) -> Renderer:
        """The OpenCV renderer of this world's camera, made on first use (two threads that draw
        frames call this under ``self._render_lock``, as :meth:`render` does)."""
        if self._renderer is None:
            from robot_daemon.plant.render import Renderer

            r = self.settings.render
            self._renderer = Renderer(
                r.camera,
                self.settings.field,
                noise=r.noise,
                light_variation=r.light_variation,
                blur=r.blur,
                seed=self._seed,
            )
        return self._renderer

    def ball_distance(self) -> float | None:
        """Distance (m) from the body to the ball on the ground, None without a ball."""
        with self.lock:
            b = self._ball_now()
            if b is None:
                return None
            x, y, _, _ = self._robot()
            return math.hypot(b.x - x, b.y - y)
