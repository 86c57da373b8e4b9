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
``pushes=(lo, hi)`` shoves the robot with an impulse of lo..hi N·s every ``push_every`` s
(training for balance; ``pushes_back`` another range for the backward ones); ``fast=False``
steps the stack's full model in the fast backend.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from schemas.policy import N_JOINTS, OBSERVATION_SIZE, OBSERVATION_SLICES

_AT = OBSERVATION_SLICES

SETTLE_S = 3.0
PUSH_S = 0.1  # s a shove lasts


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
        fast: bool = True,
        pushes: tuple[float, float] | None = None,
        push_every: tuple[float, float] = (1.0, 3.0),
        push_spread: float = np.pi,
        pushes_back: tuple[float, float] | None = None,
    ) -> None:
        if backend == "fast":
            from clients.learn.fast import FastBackend

            self.backend: Any = FastBackend(rate_hz, fast=fast)
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
        self.pushes = pushes
        self.push_every = push_every
        self.push_spread = push_spread
        self.pushes_back = pushes_back
        self._next_push = np.inf
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
        self.backend.reset(mode, opts.get("pose"), seed)
        obs = self._vector()
        if mode != "fallen":
            obs = self._settle(obs)
        self.steps = 0
        self._next_push = self._push_time()
        return obs, {"time": self.backend.time}

    def _push_time(self) -> float:
        if self.pushes is None:
            return np.inf
        return self.steps / self.rate_hz + float(self.np_random.uniform(*self.push_every))

    def _shove(self) -> None:
        """A shove of a random impulse (N·s, ``pushes``; ``pushes_back`` for backward ones
        when given: the robot takes less forward) over 0.1 s, forward or backward turned by up
        to ``push_spread`` rad (π: any horizontal direction; MuJoCo Playground's push
        perturbation)."""
        assert self.pushes is not None
        back = int(self.np_random.integers(2))
        span = self.pushes_back if back and self.pushes_back is not None else self.pushes
        impulse = float(self.np_random.uniform(*span))
        ahead = float(back) * np.pi
        angle = ahead + float(self.np_random.uniform(-self.push_spread, self.push_spread))
        force = impulse / PUSH_S
        self.backend.push((force * np.cos(angle), force * np.sin(angle), 0.0), PUSH_S)
        self._next_push = self._push_time()

    def _vector(self) -> np.ndarray:
        vector = getattr(self.backend, "vector", None)
        if vector is not None:  # the fast backend's path: no message built
            return vector()
        return np.asarray(self.backend.observation().vector(), np.float32)

    def _settle(self, obs: np.ndarray) -> np.ndarray:
        """Hold the start pose until the body is still (|gyro| < 0.05 rad/s for 0.5 s, at most
        ``SETTLE_S``): the stack's stand page and the fast backend's drop into the pose both
        leave it rocking, and an episode should start from rest."""
        hold = obs[_AT["last_action"]].astype(float)
        still = 0
        # The stack places the robot upright on its soles and it then leans into the pose: a
        # still moment before the lean is not rest.
        at_least = int(getattr(self.backend, "settle_min_s", 0.0) * self.rate_hz)
        for k in range(int(SETTLE_S * self.rate_hz)):
            self.backend.apply(hold)
            self.backend.advance(1.0 / self.rate_hz)
            obs = self._vector()
            still = still + 1 if np.max(np.abs(obs[_AT["gyro"]])) < 0.05 else 0
            if still >= self.rate_hz / 2 and k >= at_least:
                break
        return obs

    def step(self, action: Any):
        a = np.asarray(action, dtype=float)
        if a.shape != (N_JOINTS,) or not np.all(np.isfinite(a)):
            raise ValueError(f"action must be {N_JOINTS} finite numbers, got shape {a.shape}")
        if self.steps / self.rate_hz >= self._next_push:
            self._shove()
        clipped = self.backend.apply(a)
        self.backend.advance(1.0 / self.rate_hz)
        obs = self._vector()
        why = self.backend.termination()
        self.steps += 1
        reward = 0.0 if why else self.reward(obs, a)
        info = {"time": self.backend.time, "termination": why, "clipped": clipped}
        return obs, reward, bool(why), self.steps >= self.max_steps, info

    @staticmethod
    def reward(obs: np.ndarray, action: np.ndarray) -> float:
        """Alive, upright, near the stand pose, small actions (a step that ends the episode
        earns 0)."""
        upright = -float(obs[_AT["gravity"]][2])
        q = obs[_AT["joint_pos"]]
        pose_err = float(q @ q) / len(q)
        return 1.0 + upright - 0.5 * pose_err - 0.01 * float(action @ action) / len(action)

    def push(self, force: tuple[float, float, float], duration: float = 0.1) -> None:
        """A shove at the torso (N, field frame), in either backend."""
        self.backend.push(force, duration)

    def close(self) -> None:
        self.backend.close()


gym.register("darwin/Stand-v0", entry_point="clients.learn.env:DarwinStandEnv")
