"""A Gymnasium environment over the policy contract (schemas/policy.py), registered as
``darwin/Stand-v0``: stand and stay standing.

    import gymnasium as gym, clients.learn.env
    env = gym.make("darwin/Stand-v0")                       # fast direct-MuJoCo backend
    env = gym.make("darwin/Stand-v0", backend="stack", robot=Robot())   # the whole stack

Observation: the 69 numbers of ``PolicyObservation.vector()`` (gyro, gravity, command, joint
positions relative to the default pose, joint velocities, last action). Action: 20 offsets in
[−1, 1], × ``scale`` rad from the default pose. An episode ends (``terminated``) on the daemon's
terminations (a fall: −gravity_z < 0.85; a joint past its limit) and is truncated after
``max_steps``. ``reset(seed=…, options={"mode": "standing" | "fallen" | "pose", "pose": [...]})``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from schemas.policy import N_JOINTS, OBSERVATION_SIZE

SETTLE_S = 3.0


class DarwinStandEnv(gym.Env):
    metadata = {"render_modes": []}

    def __init__(
        self,
        backend: str = "fast",
        robot: Any = None,
        rate_hz: float = 50.0,
        max_steps: int = 500,
        randomize: Any = None,
        reset_mode: str = "standing",
    ) -> None:
        if backend == "fast":
            from clients.learn.fast import FastBackend

            self.backend: Any = FastBackend(rate_hz)
            if randomize is not None:
                self.backend.random = randomize
        elif backend == "stack":
            if robot is None:
                raise ValueError("the stack backend needs robot=Robot(...) connected to a daemon")
            from clients.learn.stack import StackBackend

            self.backend = StackBackend(robot, rate_hz)
        else:
            raise ValueError(f"backend {backend!r} is not 'fast' or 'stack'")
        self.rate_hz = rate_hz
        self.max_steps = max_steps
        self.reset_mode = reset_mode
        self.observation_space = spaces.Box(-np.inf, np.inf, (OBSERVATION_SIZE,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (N_JOINTS,), np.float32)
        self.steps = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        opts = options or {}
        if seed is None:
            seed = int(self.np_random.integers(2**31))
        mode = opts.get("mode", self.reset_mode)
        obs = self.backend.reset(mode, opts.get("pose"), seed)
        if mode != "fallen":
            obs = self._settle(obs)
        self.steps = 0
        return np.asarray(obs.vector(), np.float32), {"time": self.backend.time}

    def _settle(self, obs: Any) -> Any:
        """Hold the start pose until the body is still (|gyro| < 0.05 rad/s for 0.5 s, at most
        ``SETTLE_S``): the stack's stand page and the fast backend's drop into the pose both
        leave it rocking, and an episode should start from rest."""
        hold = np.asarray(obs.last_action, dtype=float)
        still = 0
        for _ in range(int(SETTLE_S * self.rate_hz)):
            self.backend.apply(hold)
            self.backend.advance(1.0 / self.rate_hz)
            obs = self.backend.observation()
            still = still + 1 if max(abs(g) for g in obs.gyro) < 0.05 else 0
            if still >= self.rate_hz / 2:
                break
        return obs

    def step(self, action: Any):
        a = np.asarray(action, dtype=float)
        if a.shape != (N_JOINTS,) or not np.all(np.isfinite(a)):
            raise ValueError(f"action must be {N_JOINTS} finite numbers, got shape {a.shape}")
        clipped = self.backend.apply(a)
        self.backend.advance(1.0 / self.rate_hz)
        obs = self.backend.observation()
        why = self.backend.termination()
        self.steps += 1
        upright = -obs.gravity[2]
        pose_err = float(np.mean(np.square(obs.joint_pos)))
        reward = 0.0 if why else 1.0 + upright - 0.5 * pose_err - 0.01 * float(np.mean(a * a))
        info = {"time": self.backend.time, "termination": why, "clipped": clipped}
        return (
            np.asarray(obs.vector(), np.float32),
            reward,
            bool(why),
            self.steps >= self.max_steps,
            info,
        )

    def push(self, force: tuple[float, float, float], duration: float = 0.1) -> None:
        """A shove at the torso (N, field frame), in either backend."""
        self.backend.push(force, duration)

    def close(self) -> None:
        self.backend.close()


gym.register("darwin/Stand-v0", entry_point=DarwinStandEnv)
