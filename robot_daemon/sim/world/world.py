"""The simulated world: the robot's body on a field, a ball, and the camera's view.

One :class:`SimWorld` lives where the emulator lives. :meth:`step` takes the servos' present
positions (servo angles, rad, by id) and a time step, moves the body (support-foot odometry,
falls), rolls the ball and kicks it when a foot sweeps through it, and returns what the IMU
feels. :meth:`attach` hooks it to an :class:`~robot_daemon.sim.emulator.Emulator`, so every
physics step of the servos is a step of the world and the CM-730 reports the body's motion.

Every public method is thread-safe: the emulator's thread steps the world while the control
queryable places things and the camera renders.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from config.loader import load_all
from robot_daemon.sim.world.ball import Ball
from robot_daemon.sim.world.body import Body
from robot_daemon.sim.world.render import BallView, CameraPose, Renderer
from robot_daemon.sim.world.settings import WorldSettings
from schemas.kinematics import SIDES, camera_pose
from schemas.messages import World

if TYPE_CHECKING:
    from robot_daemon.sim.emulator import Emulator


PLANTS = ("kinematic", "mujoco")


def make_world(
    plant: str,
    settings: WorldSettings | None = None,
    config: dict[str, Any] | None = None,
    seed: int | None = None,
) -> Any:
    """The world for ``plant`` (``[emulator] physics``): the kinematic :class:`SimWorld`, or the
    MuJoCo plant (needs the physics extra; a missing one is a RuntimeError naming the fix).
    ``config`` is the merged config, for ``[physics]``."""
    if plant == "kinematic":
        return SimWorld(settings, seed=seed)
    if plant == "mujoco":
        from robot_daemon.sim.physics.model import PhysicsSettings
        from robot_daemon.sim.physics.world import MujocoWorld, import_mujoco

        import_mujoco()
        physics = PhysicsSettings.from_config(config if config is not None else load_all())
        return MujocoWorld(settings, seed=seed, physics=physics)
    raise ValueError(f"unknown physics plant {plant!r}; plants: {', '.join(PLANTS)}")


class SimWorld:
    def __init__(self, settings: WorldSettings | None = None, seed: int | None = None) -> None:
        self.settings = s = settings or WorldSettings()
        self.lock = threading.RLock()
        self.body = Body(s.feet, s.falls, s.imu)
        self.ball = Ball(s.ball, s.feet)
        self.time = 0.0
        self.falls = 0  # how many times the robot fell
        self.frames_rendered = 0  # frames served to the camera source
        self._positions: dict[int, float] = {}
        self._render_lock = threading.Lock()
        self._renderer = Renderer(
            s.render.camera,
            s.field,
            noise=s.render.noise,
            light_variation=s.render.light_variation,
            blur=s.render.blur,
            seed=seed,
        )
        self.body.place(*s.robot_start)
        if s.ball_start is not None:
            self.ball.place(*s.ball_start)

    # -- stepping ------------------------------------------------------------------------------
    def step(self, dt: float, positions: Mapping[int, float]) -> tuple[np.ndarray, np.ndarray]:
        """Advance by ``dt`` s with the servos at ``positions``; returns (gyro, accel) for the
        IMU in robot axes (rad/s, m/s²)."""
        with self.lock:
            self._positions = dict(positions)
            was = self.body.fallen
            self.body.update(self._positions, dt)
            if self.body.fallen != "none" and was == "none":
                self.falls += 1
            if self.body.fallen == "none":
                soles = [(self.body.soles_w[s], self.body.sole_velocity[s]) for s in SIDES]
            else:
                soles = []
            self.ball.step(dt, soles)
            self.time += dt
            return self.body.imu()

    def attach(self, emulator: Emulator) -> None:
        """Step with every physics step of ``emulator`` and feed its IMU."""

        def hook(dt: float, emu: Emulator) -> None:
            gyro, accel = self.step(dt, emu.present_positions())
            emu.set_body_motion(gyro.tolist(), accel.tolist())

        emulator.add_physics_hook(hook)
        self._hook = hook

    def detach(self, emulator: Emulator) -> None:
        hook = getattr(self, "_hook", None)
        if hook is not None:
            emulator.remove_physics_hook(hook)
            self._hook = None

    # -- placing ---------------------------------------------------------------------------------
    def place_robot(self, x: float, y: float, yaw: float) -> None:
        """Stand the robot at (x, y) facing ``yaw`` (rad); clears a fall."""
        with self.lock:
            self.body.place(x, y, yaw)
            if self._positions:
                self.body.update(self._positions, 0.0)

    def place_ball(self, x: float, y: float, vx: float = 0.0, vy: float = 0.0) -> None:
        with self.lock:
            self.ball.place(x, y, vx, vy)

    def remove_ball(self) -> None:
        with self.lock:
            self.ball.remove()

    def push(self, force: tuple[float, float, float], duration: float) -> None:
        """A shove on the torso (N, field frame, for ``duration`` s). The kinematic body has no
        dynamics: a horizontal impulse above ``[world.falls] push_fall_impulse`` tips it over
        the way it was pushed (forward or backward relative to its heading), a smaller one does
        nothing."""
        with self.lock:
            if self.body.fallen != "none":
                return
            ix, iy = force[0] * duration, force[1] * duration
            if math.hypot(ix, iy) < self.settings.falls.push_fall_impulse:
                return
            heading = self.body.heading()
            along = ix * math.cos(heading) + iy * math.sin(heading)
            self.body._fall("forward" if along >= 0 else "backward")
            self.falls += 1

    # -- observing -----------------------------------------------------------------------------
    def snapshot(self) -> World:
        """The World message (field frame, metres, radians)."""
        with self.lock:
            st = self.body.state()
            b = self.ball.state
            ball: dict[str, Any] = (
                {"x": float(b.x), "y": float(b.y), "vx": float(b.vx), "vy": float(b.vy)}
                if b is not None
                else {}
            )
            return World(
                robot={"x": float(st.x), "y": float(st.y), "yaw": float(st.yaw)},
                ball=ball,
                fallen=st.fallen,
                sim_time=self.time,
                stamp=time.time(),
            )

    def camera_view(self) -> tuple[CameraPose, BallView | None]:
        with self.lock:
            t = self.body.T_wb @ camera_pose(self._positions)
            b = self.ball.state
            s = self.settings.ball
            ball = BallView(b.x, b.y, s.radius, s.color) if b is not None else None
            return CameraPose(t[:3, 3].copy(), t[:3, :3].copy()), ball

    def render(self) -> np.ndarray:
        """The camera image (BGR, uint8) of the world as it is now."""
        pose, ball = self.camera_view()
        with self._render_lock:
            return self._renderer.render(pose, ball)

    def ball_distance(self) -> float | None:
        """Distance (m) from the body to the ball on the ground, None without a ball."""
        with self.lock:
            b = self.ball.state
            if b is None:
                return None
            return math.hypot(b.x - self.body.T_wb[0, 3], b.y - self.body.T_wb[1, 3])
