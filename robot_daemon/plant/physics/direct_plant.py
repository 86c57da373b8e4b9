"""The MuJoCo plant driven directly, without an emulator: servo goals in, joint and IMU
readings out. The public face the learning code (clients/learn/fast.py) steps.

It is :class:`MujocoWorld` itself (the same model, from the same generator, and the same servo
model in ``step_plant``: P gain → stiffness, back-EMF, torque limit, the firmware's set point)
with the emulator's registers replaced by arrays: every servo powered at 12 V, torque on, its P
gain from the robot config (× ``kp_scale``), no moving-speed profile (the policy loop writes
goals with speed 0, the motor's own top speed). Built with ``fast=True`` it is the training model
(``[physics.fast]`` in config/physics.toml: a longer timestep, no ball; the robot, its servos
and its contacts unchanged).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from config.loader import load_all
from robot_daemon.plant.physics.mjcf_model import FLOOR, IMU_SITE, PhysicsSettings
from robot_daemon.plant.physics.mujoco_world import MujocoWorld
from robot_daemon.plant.world_settings import WorldSettings
from schemas import units


class DirectPlant(MujocoWorld):
    def __init__(
        self,
        p_gains: np.ndarray,
        physics: PhysicsSettings | None = None,
        fast: bool = True,
        config: dict[str, Any] | None = None,
    ) -> None:
        if physics is None:
            physics = PhysicsSettings.from_config(config if config is not None else load_all(),
                                                  fast=fast)  # fmt: skip
        super().__init__(WorldSettings(ball_start=None), seed=0, physics=physics)
        n = len(self.servo_ids)
        self.goal = np.zeros(n)
        self.p_gain = np.asarray(p_gains, dtype=float)
        self.kp_scale = 1.0
        self.kd_scale = 1.0
        self.gyro = np.zeros(3)
        self.accel = np.array([0.0, 0.0, units.GRAVITY])
        mj, m = self.mj, self.model
        self.joint_dofs = self._dadr  # the servo joints' dof addresses (randomization)
        self.torso = self._torso
        self.floor_geom = mj.mj_name2id(m, mj.mjtObj.mjOBJ_GEOM, FLOOR)
        self._imu_site = mj.mj_name2id(m, mj.mjtObj.mjOBJ_SITE, IMU_SITE)
        self._no_speed = np.full(n, np.inf)
        self._unsaturated = np.zeros(n, dtype=bool)
        self._gains: tuple[float, float] | None = None  # the kp/kd scales written to the model
        self._kp = np.zeros(n)

    def _commands(self, emulator: Any) -> tuple[np.ndarray, ...]:
        n = len(self.servo_ids)
        kp = self.p_gain * self.physics.stiffness_per_p * self.kp_scale
        kd = np.full(n, self.physics.emf_damping * self.kd_scale)
        force = np.full(n, self.physics.stall_torque)  # 12 V, torque limit 1023
        return self.goal, self._no_speed, kp, kd, force

    def _report(self, emulator: Any, dt: float, saturated: np.ndarray) -> None:
        d = self.data
        self.gyro = d.sensordata[self._gyro_adr : self._gyro_adr + 3].copy()
        self.accel = d.sensordata[self._accel_adr : self._accel_adr + 3].copy()

    @property
    def q(self) -> np.ndarray:
        """Joint angles (rad, servo order) now."""
        return self.data.qpos[self._qadr]

    @property
    def qd(self) -> np.ndarray:
        """Joint speeds (rad/s) now."""
        return self.data.qvel[self._dadr]

    def step(self, dt: float) -> None:
        """``dt`` s of physics toward the present ``goal`` (rad, servo order): the emulator's
        ``step_plant`` without the registers, its falls or ball touches, and with the motors'
        gains written only when they change (a reset, new ``kp_scale``/``kd_scale``)."""
        n = self._due(dt)
        if n <= 0:
            return
        gains = (self.kp_scale, self.kd_scale)
        if gains != self._gains:
            _, _, self._kp, kd, force = self._commands(None)
            self._set_servos(self._kp, kd, force)
            self._gains = gains
        if self.goal is not self._setpoint:
            # No moving-speed profile and torque on: the set point is the goal at once
            # (``_move_setpoint`` with infinite speed), written when a new goal comes.
            self._setpoint = self.goal
            self.data.ctrl[self._act] = self.goal
        self._run(n)
        self._report(None, n * self.model.opt.timestep, self._unsaturated)

    def reset(self, pose: np.ndarray, lying: str = "") -> None:
        """A fresh state (the solver's warm start too, so a seed replays an episode): the robot
        in ``pose`` (rad), standing on its soles, or lying on its ``"front"`` or ``"back"``."""
        mj, d = self.mj, self.data
        with self.lock:
            mj.mj_resetData(self.model, d)
            self._gains = None
            self._debt = 0.0
            self._positions = np.asarray(pose, dtype=float).copy()
            self._place_robot_now(0.0, 0.0, 0.0)
            if lying:
                self._lie_down(lying == "back")
            self._setpoint = self._positions.copy()
            self.goal = self._positions.copy()
            self.released = True
            d.xfrc_applied[:] = 0.0
            self._push_until = None
            mj.mj_forward(self.model, d)
        self._report(None, 0.0, np.zeros(len(self.servo_ids), dtype=bool))

    def _lie_down(self, on_back: bool) -> None:
        d = self.data
        q = self._root_q
        angle = -math.pi / 2 if on_back else math.pi / 2  # about y: face up or down
        d.qpos[q + 3 : q + 7] = (math.cos(angle / 2), 0.0, math.sin(angle / 2), 0.0)
        self.mj.mj_kinematics(self.model, d)
        lowest = min(self._geom_bottom(g) for g in self._robot_geoms)
        d.qpos[q + 2] += 0.002 - lowest

    def true_gravity(self) -> np.ndarray:
        """The unit gravity direction in the IMU's frame, from the state (not the sensors)."""
        r = self.data.site_xmat[self._imu_site].reshape(3, 3)
        return -r[2].copy()

    def torso_height(self) -> float:
        return float(self.data.xpos[self._torso][2])

    def close(self) -> None:
        close = getattr(self.camera, "close", None)
        if close is not None:
            close()
