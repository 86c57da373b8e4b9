"""The fast backend: the emulator's MuJoCo plant driven directly, no bus, no daemon.

Same robot and servo model as ``darwin up --physics mujoco`` (:class:`DirectPlant` is the
emulator's plant, ``MujocoWorld.step_plant``: P gain → stiffness, back-EMF, torque limit), built
as the training model (``[physics.fast]``: 4 ms physics steps, no ball; ``fast=False`` gives the
stack's model: 1 ms, with the ball), the same
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
from robot_daemon.plant.physics import DirectPlant
from schemas import units
from schemas.joints import JOINT_IDS, JOINT_NAMES
from schemas.policy import (
    ACTION_BOUND,
    DEFAULT_POSE,
    OBSERVATION_SIZE,
    OBSERVATION_SLICES,
    PolicyObservation,
)

_AT = OBSERVATION_SLICES


@dataclass
class Randomization:
    """Domain randomization of the plant at each reset, MuJoCo Playground OP3's ranges by
    default (floor friction 0.4–1.0, joint friction ×0.9–1.1, armature ×1.0–1.05, link
    masses ×0.9–1.1, torso ±0.3 kg, Kp and damping ×0.8–1.2); latency (s), IMU noise
    (std, rad/s and m/s²) and ``hold`` are ours. ``hold`` (lo, hi): each episode draws a
    longest hold of lo..hi policy steps, and each sensor reading (joints, gyro, gravity) is
    then held for 1..that many steps before the next: on a loaded machine the simulated
    stack's readings hold for 2–4 steps (the emulator steps the plant by the time elapsed since
    it last ran). ``Randomization.off()`` is the nominal plant."""

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
    hold: tuple[int, int] = (1, 1)

    @classmethod
    def off(cls) -> Randomization:
        one = (1.0, 1.0)
        return cls((1.0, 1.0), one, one, one, (0.0, 0.0), one, one, (0.0, 0.0), 0.0, 0.0)


class FastBackend:
    """One simulated robot stepped at the policy rate, many times faster than real time.

    ``fast=False`` steps the stack's own model (1 ms, with the ball) instead of the training
    model: tests compare the two."""

    def __init__(
        self,
        rate_hz: float = 50.0,
        tick_ms: float = 8.0,
        settings: dict | None = None,
        fast: bool = True,
    ):
        cfg = settings if settings is not None else load_all()
        self.robot = load_robot()
        self.policy = PolicySettings.from_config(cfg.get("policy"))
        self.rate_hz = rate_hz
        self.tick_s = tick_ms / 1000.0
        p = np.array([self.robot.by_id[j].p for j in JOINT_IDS])
        self.plant = DirectPlant(p, fast=fast, config=cfg)
        assert list(self.plant.servo_ids) == list(JOINT_IDS), "servo order differs"
        self.low = np.array([self.robot.by_id[j].min_rad for j in JOINT_IDS])
        self.high = np.array([self.robot.by_id[j].max_rad for j in JOINT_IDS])
        margin = math.radians(self.policy.limit_margin_deg)
        self._low_hit, self._high_hit = self.low - margin, self.high + margin
        self.default = np.array(DEFAULT_POSE)
        self.scale = self.policy.scale
        self.filter = GravityFilter(self.policy.filter_tau)
        self.rng = np.random.default_rng()
        self.random = Randomization.off()
        self._nominal = self._save_nominal()
        self.time = 0.0
        self._until = 0.0  # the time the ticks run to (the sum of what advance() was asked)
        self.tick = 0
        self.target = self.default.copy()
        self.last_action = np.zeros(len(JOINT_IDS))
        self.command = [0.0, 0.0, 0.0]
        self.latency = 0.0
        self._pending: list[tuple[float, np.ndarray]] = []
        self._gyro_now = np.zeros(3)
        self.hold_max = 1  # steps a sensor reading may hold (Randomization.hold)
        self._held: np.ndarray | None = None
        self._held_left = 0

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
        m.geom_friction[pl.floor_geom, 0] = u(r.floor_friction)
        dofs = pl.joint_dofs
        m.dof_frictionloss[:] = nom["dof_frictionloss"]
        m.dof_frictionloss[dofs] *= rng.uniform(*r.joint_friction, size=len(dofs))
        m.dof_armature[:] = nom["dof_armature"]
        m.dof_armature[dofs] *= rng.uniform(*r.armature, size=len(dofs))
        m.body_mass[:] = nom["body_mass"] * rng.uniform(*r.link_mass, size=m.nbody)
        m.body_mass[0] = nom["body_mass"][0]
        m.body_mass[pl.torso] = max(0.05, m.body_mass[pl.torso] + u(r.torso_mass_add))
        pl.kp_scale, pl.kd_scale = u(r.kp), u(r.damping)
        self.latency = u(r.latency)
        # Drawn only when asked for: the nominal and Playground worlds keep their seeded draws.
        self.hold_max = int(rng.integers(r.hold[0], r.hold[1] + 1)) if r.hold != (1, 1) else 1

    # -- episodes -------------------------------------------------------------------------
    def reset(self, mode: str = "standing", pose: Any = None, seed: int | None = None):
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        self._randomize()
        start = self.default.copy() if pose is None else np.asarray(pose, dtype=float)
        if start.shape != (len(JOINT_IDS),):
            raise ValueError(f"pose must be {len(JOINT_IDS)} angles in rad (schemas.policy order)")
        if mode not in ("standing", "pose", "fallen"):
            raise ValueError(f"reset mode {mode!r} is not one of standing, fallen, pose")
        start = np.clip(start, self.low, self.high)
        lying = ("back" if self.rng.integers(2) else "front") if mode == "fallen" else ""
        self.plant.reset(start, lying)
        self.time, self.tick, self._until = 0.0, 0, 0.0
        self.target = start.copy()
        self.last_action = (start - self.default) / self.scale
        self._pending = []
        self._held, self._held_left = None, 0
        # The filter starts from the true attitude (the accelerometer reads nothing useful before
        # the first step); the daemon's starts from its first sample, the robot at rest.
        self.filter.set(self.plant.true_gravity())
        self._gyro_now = self._gyro()
        return self.observation()

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
        asked = self.default + self.scale * a
        want = np.clip(asked, self.low, self.high)
        if np.any(want != asked):
            clipped.append("joint limits")
        self._pending.append((self.time + self.latency, want))
        return clipped

    def advance(self, seconds: float) -> None:
        """Run the control ticks and the plant for ``seconds``."""
        # Against a schedule, not the last tick: at 50 Hz on 8 ms ticks the steps take 3, 2,
        # 3, 2 ticks as the daemon's do, not 3 every time.
        self._until += seconds
        end = self._until - 1e-9
        pl, delta, tick = self.plant, self.policy.max_delta, self.tick_s
        per_unit = units.RAD_PER_UNIT
        while self.time < end:
            if self._pending and self._pending[0][0] <= self.time + 1e-9:
                while self._pending and self._pending[0][0] <= self.time + 1e-9:
                    _, want = self._pending.pop(0)
                    self.target = self.target + np.clip(want - self.target, -delta, delta)
                self.last_action = (self.target - self.default) / self.scale
                # Goals go to the servo as whole position units, as the bus writes them.
                pl.goal = np.round(self.target / per_unit) * per_unit
            pl.step(tick)
            self.time += tick
            self.tick += 1
            self._gyro_now = self._gyro()
            self.filter.update(self._gyro_now, self._accel(), tick)

    def _gyro(self) -> np.ndarray:
        n = self.random.gyro_noise
        return self.plant.gyro + self.rng.normal(0, n, 3) if n else self.plant.gyro

    def _accel(self) -> np.ndarray:
        n = self.random.accel_noise
        return self.plant.accel + self.rng.normal(0, n, 3) if n else self.plant.accel

    def vector(self) -> np.ndarray:
        """The observation as :meth:`PolicyObservation.vector` lays it out, without building
        the message (the training loop's path)."""
        pl = self.plant
        q = np.round(pl.q / units.RAD_PER_UNIT) * units.RAD_PER_UNIT  # the encoder's units
        out = np.empty(OBSERVATION_SIZE, np.float32)
        out[_AT["gyro"]] = self._gyro_now
        out[_AT["gravity"]] = self.filter.g
        out[_AT["command"]] = self.command
        out[_AT["joint_pos"]] = q - self.default
        out[_AT["joint_vel"]] = pl.qd
        out[_AT["last_action"]] = self.last_action
        if self.hold_max > 1:
            # The sensor readings as a starved stack reports them: held for steps; the last
            # action and the command are the daemon's own, never stale.
            if self._held is not None and self._held_left > 0:
                self._held_left -= 1
                keep = out[_AT["last_action"]].copy(), out[_AT["command"]].copy()
                out[:] = self._held
                out[_AT["last_action"]], out[_AT["command"]] = keep
            else:
                self._held = out.copy()
                self._held_left = int(self.rng.integers(self.hold_max))
        return out

    def observation(self) -> PolicyObservation:
        v = self.vector().astype(float)
        return PolicyObservation(
            joint_pos=v[_AT["joint_pos"]].tolist(),
            joint_vel=v[_AT["joint_vel"]].tolist(),
            gyro=v[_AT["gyro"]].tolist(),
            gravity=list(self.filter.g),
            last_action=self.last_action.tolist(),
            command=list(self.command),
            stamp=self.time,
            tick=self.tick,
            running=True,
        )

    def termination(self) -> str:
        """The daemon's terminations that a plant can have: a fall, a joint past its limit."""
        if self.filter.upright < self.policy.upright_min:
            return "fall"
        q = self.plant.q
        hit = (q < self._low_hit) | (q > self._high_hit)
        if hit.any():
            return "joint limit hit: " + ", ".join(
                n for n, h in zip(JOINT_NAMES, hit, strict=True) if h
            )
        return ""

    def torso_height(self) -> float:
        return self.plant.torso_height()

    def close(self) -> None:
        self.plant.close()
