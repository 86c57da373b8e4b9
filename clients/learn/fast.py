"""The fast backend: the emulator's MuJoCo plant driven directly, no bus, no daemon.

Same model and servo model as ``darwin up --physics mujoco`` (:class:`MujocoWorld`'s
``step_plant``: P gain → stiffness, moving-speed profile, back-EMF, torque limit), the same
observation and action (schemas/policy.py) and the same rules as the daemon's policy loop: the
action becomes targets clipped to the joint limits and to ``max_delta``, written as whole servo
units at the daemon's tick, the gravity from the same filter on the IMU site's gyro and
accelerometer, the same terminations. What it leaves out is the bus: no quantised velocity
register, no 10-bit ADC, no wire latency (``Randomization.latency`` puts latency back).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from config.loader import load_all, load_robot
from robot_daemon.motion.attitude import GravityFilter
from robot_daemon.motion.policy import PolicySettings
from robot_daemon.plant.physics.mjcf_model import IMU_SITE, PhysicsSettings
from robot_daemon.plant.physics.mujoco_world import MujocoWorld
from robot_daemon.plant.world_settings import WorldSettings
from schemas import units
from schemas.joints import JOINT_IDS, JOINT_NAMES
from schemas.policy import ACTION_BOUND, DEFAULT_POSE, PolicyObservation


@dataclass
class Randomization:
    """Domain randomization of the plant at each reset, MuJoCo Playground OP3's ranges by
    default (floor friction 0.4–1.0, joint friction ×0.9–1.1, armature ×1.0–1.05, link
    masses ×0.9–1.1, torso ±0.3 kg, Kp and damping ×0.8–1.2); latency (s) and IMU noise
    (std, rad/s and m/s²) are ours. ``Randomization.off()`` is the nominal plant."""

    floor_friction: tuple[float, float] = (0.4, 1.0)
    joint_friction: tuple[float, float] = (0.9, 1.1)
    armature: tuple[float, float] = (1.0, 1.05)
    link_mass: tuple[float, float] = (0.9, 1.1)
    torso_mass_add: tuple[float, float] = (-0.3, 0.3)
    kp: tuple[float, float] = (0.8, 1.2)
    damping: tuple[float, float] = (0.8, 1.2)
    latency: tuple[float, float] = (0.0, 0.01)
    gyro_noise: float = 0.02
    accel_noise: float = 0.1

    @classmethod
    def off(cls) -> Randomization:
        one = (1.0, 1.0)
        return cls((1.0, 1.0), one, one, one, (0.0, 0.0), one, one, (0.0, 0.0), 0.0, 0.0)


class _Plant(MujocoWorld):
    """The world with the emulator replaced by three arrays: the servo commands in, the
    sensors out."""

    def __init__(self, physics: PhysicsSettings, p_gains: np.ndarray) -> None:
        settings = WorldSettings(ball_start=None)
        super().__init__(settings, seed=0, physics=physics)
        n = len(self.servo_ids)
        self.goal = np.zeros(n)
        self.p_gain = p_gains.astype(float)
        self.kp_scale = 1.0
        self.kd_scale = 1.0
        self.q = np.zeros(n)
        self.qd = np.zeros(n)
        self.gyro = np.zeros(3)
        self.accel = np.array([0.0, 0.0, units.GRAVITY])

    def _commands(self, emulator: Any) -> tuple[np.ndarray, ...]:
        n = len(self.servo_ids)
        on = np.ones(n)
        kp = self.p_gain * self.physics.stiffness_per_p * self.kp_scale
        kd = np.full(n, self.physics.emf_damping * self.kd_scale)
        force = np.full(n, self.physics.stall_torque)  # 12 V, torque limit 1023
        return self.goal, np.full(n, np.inf), kp * on, kd, force

    def _report(self, emulator: Any, dt: float, saturated: np.ndarray) -> None:
        d = self.data
        self.q = d.qpos[self._qadr].copy()
        self.qd = d.qvel[self._dadr].copy()
        self.gyro = d.sensordata[self._gyro_adr : self._gyro_adr + 3].copy()
        self.accel = d.sensordata[self._accel_adr : self._accel_adr + 3].copy()


class FastBackend:
    """One simulated robot stepped at the policy rate, many times faster than real time."""

    def __init__(self, rate_hz: float = 50.0, tick_ms: float = 8.0, settings: dict | None = None):
        cfg = settings if settings is not None else load_all()
        self.robot = load_robot()
        self.policy = PolicySettings.from_config(cfg.get("policy"))
        self.rate_hz = rate_hz
        self.tick_s = tick_ms / 1000.0
        p = np.array([self.robot.by_id[j].p for j in JOINT_IDS])
        self.plant = _Plant(PhysicsSettings.from_config(cfg.get("physics") or {}), p)
        assert list(self.plant.servo_ids) == list(JOINT_IDS), "servo order differs"
        self.low = np.array([self.robot.by_id[j].min_rad for j in JOINT_IDS])
        self.high = np.array([self.robot.by_id[j].max_rad for j in JOINT_IDS])
        self.default = np.array(DEFAULT_POSE)
        self.scale = self.policy.scale
        self.filter = GravityFilter(self.policy.filter_tau)
        self.rng = np.random.default_rng()
        self.random = Randomization.off()
        self._nominal = self._save_nominal()
        self.time = 0.0
        self.tick = 0
        self.target = self.default.copy()
        self.last_action = np.zeros(len(JOINT_IDS))
        self.command = [0.0, 0.0, 0.0]
        self.latency = 0.0
        self._pending: list[tuple[float, np.ndarray]] = []

    # -- randomization --------------------------------------------------------------------
    def _save_nominal(self) -> dict[str, np.ndarray]:
        m = self.plant.model
        return {
            "geom_friction": m.geom_friction.copy(),
            "dof_frictionloss": m.dof_frictionloss.copy(),
            "dof_armature": m.dof_armature.copy(),
            "body_mass": m.body_mass.copy(),
        }

    def _randomize(self) -> None:
        r, m, rng, nom, pl = self.random, self.plant.model, self.rng, self._nominal, self.plant
        u = lambda lo_hi: rng.uniform(*lo_hi)  # noqa: E731
        m.geom_friction[:] = nom["geom_friction"]
        floor = pl.mj.mj_name2id(m, pl.mj.mjtObj.mjOBJ_GEOM, "floor")
        m.geom_friction[floor, 0] = u(r.floor_friction)
        dofs = pl._dadr
        m.dof_frictionloss[:] = nom["dof_frictionloss"]
        m.dof_frictionloss[dofs] *= rng.uniform(*r.joint_friction, size=len(dofs))
        m.dof_armature[:] = nom["dof_armature"]
        m.dof_armature[dofs] *= rng.uniform(*r.armature, size=len(dofs))
        m.body_mass[:] = nom["body_mass"] * rng.uniform(*r.link_mass, size=m.nbody)
        m.body_mass[0] = nom["body_mass"][0]
        m.body_mass[pl._torso] = max(0.05, m.body_mass[pl._torso] + u(r.torso_mass_add))
        pl.kp_scale, pl.kd_scale = u(r.kp), u(r.damping)
        self.latency = u(r.latency)

    # -- episodes -------------------------------------------------------------------------
    def reset(self, mode: str = "standing", pose: Any = None, seed: int | None = None):
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        self._randomize()
        pl = self.plant
        start = self.default.copy() if pose is None else np.asarray(pose, dtype=float)
        if start.shape != (len(JOINT_IDS),):
            raise ValueError(f"pose must be {len(JOINT_IDS)} angles in rad (schemas.policy order)")
        start = np.clip(start, self.low, self.high)
        with pl.lock:
            # A fresh state (the solver's warm start too): a seed replays the same episode.
            pl.mj.mj_resetData(pl.model, pl.data)
            pl._debt = 0.0
            pl._positions = start.copy()
            pl._place_robot_now(0.0, 0.0, 0.0)
            if mode == "fallen":
                self._lie_down(bool(self.rng.integers(2)))
            elif mode not in ("standing", "pose"):
                raise ValueError(f"reset mode {mode!r} is not one of standing, fallen, pose")
            pl._setpoint = start.copy()
            pl.goal = start.copy()
            pl.released = True
            pl.data.xfrc_applied[:] = 0.0
            pl._push_until = None
            pl.mj.mj_forward(pl.model, pl.data)
        pl._report(None, 0.0, np.zeros(len(JOINT_IDS), dtype=bool))
        self.time, self.tick = 0.0, 0
        self.target = start.copy()
        self.last_action = (start - self.default) / self.scale
        self._pending = []
        # The filter starts from the true attitude (the accelerometer reads nothing useful before
        # the first step); the daemon's starts from its first sample, the robot at rest.
        self.filter.set(self._true_gravity())
        return self.observation()

    def _true_gravity(self) -> np.ndarray:
        pl = self.plant
        site = pl.mj.mj_name2id(pl.model, pl.mj.mjtObj.mjOBJ_SITE, IMU_SITE)
        return pl.data.site_xmat[site].reshape(3, 3).T @ np.array([0.0, 0.0, -1.0])

    def _lie_down(self, on_back: bool) -> None:
        pl, d = self.plant, self.plant.data
        q = pl._root_q
        angle = -math.pi / 2 if on_back else math.pi / 2  # about y: face down or up
        d.qpos[q + 3 : q + 7] = (math.cos(angle / 2), 0.0, math.sin(angle / 2), 0.0)
        pl.mj.mj_kinematics(pl.model, d)
        lowest = min(pl._geom_bottom(g) for g in pl._robot_geoms)
        d.qpos[q + 2] += 0.002 - lowest

    def push(self, force: tuple[float, float, float], duration: float) -> None:
        self.plant.push(force, duration)

    # -- the step -------------------------------------------------------------------------
    def apply(self, action: np.ndarray) -> list[str]:
        """The daemon's rules (robot_daemon/motion/policy.py): clip to ±1, the joint limits and
        max_delta; returns what was clipped. Applied after ``latency``."""
        a = np.asarray(action, dtype=float)
        clipped = []
        if np.any(np.abs(a) > ACTION_BOUND):
            clipped.append("action")
            a = np.clip(a, -ACTION_BOUND, ACTION_BOUND)
        want = np.clip(self.default + self.scale * a, self.low, self.high)
        if np.any(want != self.default + self.scale * a):
            clipped.append("joint limits")
        self._pending.append((self.time + self.latency, want))
        return clipped

    def advance(self, seconds: float) -> None:
        """Run the control ticks and the plant for ``seconds``."""
        end = self.time + seconds - 1e-9
        pl = self.plant
        while self.time < end:
            while self._pending and self._pending[0][0] <= self.time + 1e-9:
                _, want = self._pending.pop(0)
                step = np.clip(want - self.target, -self.policy.max_delta, self.policy.max_delta)
                self.target = self.target + step
                self.last_action = (self.target - self.default) / self.scale
            # Goals go to the servo as whole position units, as the bus writes them.
            pl.goal = np.round(self.target / units.RAD_PER_UNIT) * units.RAD_PER_UNIT
            pl.step_plant(self.tick_s, None)  # type: ignore[arg-type]
            self.time += self.tick_s
            self.tick += 1
            self.filter.update(self._gyro(), self._accel(), self.tick_s)

    def _gyro(self) -> np.ndarray:
        n = self.random.gyro_noise
        return self.plant.gyro + (self.rng.normal(0, n, 3) if n else 0.0)

    def _accel(self) -> np.ndarray:
        n = self.random.accel_noise
        return self.plant.accel + (self.rng.normal(0, n, 3) if n else 0.0)

    def observation(self) -> PolicyObservation:
        pl = self.plant
        q = np.round(pl.q / units.RAD_PER_UNIT) * units.RAD_PER_UNIT  # the encoder's units
        return PolicyObservation(
            joint_pos=(q - self.default).tolist(),
            joint_vel=pl.qd.tolist(),
            gyro=self._gyro().tolist(),
            gravity=list(self.filter.g),
            last_action=self.last_action.tolist(),
            command=list(self.command),
            stamp=self.time,
            tick=self.tick,
            running=True,
        )

    def termination(self) -> str:
        """The daemon's terminations that a plant can have: a fall, a joint past its limit."""
        s = self.policy
        if self.filter.upright < s.upright_min:
            return "fall"
        margin = math.radians(s.limit_margin_deg)
        hit = (self.plant.q < self.low - margin) | (self.plant.q > self.high + margin)
        if hit.any():
            return "joint limit hit: " + ", ".join(
                n for n, h in zip(JOINT_NAMES, hit, strict=True) if h
            )
        return ""

    def torso_height(self) -> float:
        return float(self.plant.data.xpos[self.plant._torso][2])

    def close(self) -> None:
        self.plant.camera.close() if hasattr(self.plant.camera, "close") else None
