"""The simulated world: the robot's body on a field, a ball, and the camera's view.

One :class:`SimWorld` lives where the emulator lives. :meth:`step` takes the servos' present
positions (servo angles, rad, by id) and a time step, moves the body (support-foot odometry,
falls), rolls the ball and kicks it when a foot sweeps through it, and returns what the IMU
feels. :meth:`attach` hooks it to an :class:`~robot_daemon.emulator.emulator.Emulator`, so every
physics step of the servos is a step of the world and the CM-730 reports the body's motion.

Every public method is thread-safe: the emulator's thread steps the world while the control
queryable places things and the camera renders.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from config.loader import load_all
from robot_daemon.emulator.options import PLANTS
from robot_daemon.plant.ball import Ball, BallState
from robot_daemon.plant.camera_model import CameraPose
from robot_daemon.plant.kinematic_body import Body
from robot_daemon.plant.views import WorldViews
from robot_daemon.plant.world_settings import WorldSettings
from schemas.kinematics import SIDES, camera_pose

if TYPE_CHECKING:
    from robot_daemon.emulator.emulator import Emulator


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
        from robot_daemon.plant.physics.mjcf_model import PhysicsSettings
        from robot_daemon.plant.physics.mujoco_world import MujocoWorld, import_mujoco

        import_mujoco()
        physics = PhysicsSettings.from_config(config if config is not None else load_all())
        return MujocoWorld(settings, seed=seed, physics=physics)
    raise ValueError(f"unknown physics plant {plant!r}; plants: {', '.join(PLANTS)}")


class SimWorld(WorldViews):
    def __init__(self, settings: WorldSettings | None = None, seed: int | None = None) -> None:
        super().__init__(settings or WorldSettings(), seed)
        s = self.settings
        self.body = Body(s.feet, s.falls, s.imu)
        self.ball = Ball(s.ball, s.feet)
        self.falls = 0  # how many times the robot fell
        self._positions: dict[int, float] = {}
        # A robot standing still (most of a simulated robot's life) is stepped 100 times a
        # second to the same state: the servo positions and the state a step left unchanged,
        # and the IMU it reported, so the next such step only counts the time.
        self._rest: tuple[tuple[tuple[int, float], ...], tuple[object, ...]] | None = None
        self._rest_imu: tuple[np.ndarray, np.ndarray] = (np.zeros(3), np.zeros(3))
        self.body.place(*s.robot_start)
        if s.ball_start is not None:
            self.ball.place(*s.ball_start)

    # -- stepping ------------------------------------------------------------------------------
    def step(self, dt: float, positions: Mapping[int, float]) -> tuple[np.ndarray, np.ndarray]:
        """Advance by ``dt`` s with the servos at ``positions``; returns (gyro, accel) for the
        IMU in robot axes (rad/s, m/s²)."""
        with self.lock:
            key = tuple(positions.items())
            before = self._fingerprint()
            if self._rest is not None and self._rest == (key, before):
                self.time += dt
                gyro, accel = self._rest_imu
                return gyro.copy(), accel.copy()
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
            imu = self.body.imu()
            ball = self.ball.state
            resting = self.body.still() and (ball is None or ball.speed == 0)
            self._rest = (key, before) if resting and self._fingerprint() == before else None
            self._rest_imu = (imu[0].copy(), imu[1].copy())
            return imu

    def _fingerprint(self) -> tuple[object, ...]:
        ball = self.ball.state
        return (
            self.body.fingerprint(),
            None if ball is None else (ball.x, ball.y, ball.vx, ball.vy),
        )

    def attach(self, emulator: Emulator) -> None:
        """Step with every physics step of ``emulator`` and feed its IMU."""

        def hook(dt: float, emu: Emulator) -> None:
            gyro, accel = self.step(dt, emu.api.present_positions())
            emu.api.set_body_motion(gyro.tolist(), accel.tolist())

        emulator.add_physics_hook(hook)
        self._hook: Callable[[float, Emulator], None] | None = hook

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

    # -- observing (the rest: WorldViews) -------------------------------------------------------
    def _robot(self) -> tuple[float, float, float, str]:
        st = self.body.state()
        return st.x, st.y, st.yaw, st.fallen

    def _ball_now(self) -> BallState | None:
        return self.ball.state

    def _camera_pose(self) -> CameraPose:
        t = self.body.T_wb @ camera_pose(self._positions)
        return CameraPose(t[:3, 3].copy(), t[:3, :3].copy())
