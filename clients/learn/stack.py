"""The stack backend: the whole system as it runs on the robot (a daemon over the emulator's
MuJoCo plant, `darwin up --physics mujoco`), reached only through the key space, so the same
code drives the real robot (without the simulator's resets and pushes).

Each step sends one signed action (clients/learn/stream.py) answering the newest observation
and waits for the next observation: the daemon's clock paces it, in real time.
"""

from __future__ import annotations

import contextlib
from typing import Any

import numpy as np

from clients.learn.stream import PolicyStream
from schemas.errors import DarwinError
from schemas.policy import UPRIGHT_MIN, PolicyObservation

WAIT = 10.0


class StackBackend:
    settle_min_s = 1.5  # the environment's settle holds at least this long after a reset

    def __init__(self, robot: Any, rate_hz: float = 50.0) -> None:
        from schemas.sim_control import SimControl

        self.robot = robot
        self.rate_hz = rate_hz
        self.stream = PolicyStream(robot)
        self.sim = SimControl(robot.session, robot.target.robot)
        self.obs: PolicyObservation | None = None
        self.time = 0.0
        self._t0 = 0.0

    def reset(self, mode: str = "standing", pose: Any = None, seed: int | None = None):
        if mode == "fallen":
            raise ValueError(
                "the stack backend resets into standing or a pose; use the fast backend for "
                "fallen starts"
            )
        with contextlib.suppress(DarwinError):
            self.stream.stop()
        self.robot.command("halt")
        self.robot.acquire()
        # The stand page when off the default pose (where the robot lies, if it fell), waited
        # for by its end event, not a status polled for "not playing" (which could be one from
        # before the page started); then placed upright in that pose and, again on the
        # observations, at rest.
        self.stream.stand(timeout=WAIT)
        self.sim.call("place_robot", x=-1.0, y=0.0, yaw=0.0)
        self.stream.stand(timeout=WAIT)
        self.robot.wait_for("status", lambda s: s.motion["fall"]["state"] == "upright", WAIT)
        self.stream.start(rate_hz=self.rate_hz)
        self.obs = self.stream.next_observation(timeout=WAIT)
        if pose is not None:
            scale = self.stream.info["scale"]
            default = np.array(self.stream.info["default_pose"])
            target = (np.asarray(pose, dtype=float) - default) / scale
            for _ in range(int(self.rate_hz)):  # a second to get there at max_delta per step
                self.apply(target)
                self.advance(1.0 / self.rate_hz)
        assert self.obs is not None, "no observation from the daemon"
        self._t0 = self.obs.stamp
        self.time = 0.0
        return self.obs

    def apply(self, action: np.ndarray) -> list[str]:
        assert self.obs is not None
        self.stream.send([float(a) for a in action], self.obs.tick)
        return []

    def advance(self, seconds: float) -> None:
        assert self.obs is not None
        obs = self.stream.next_observation(self.obs.tick, timeout=WAIT)
        if obs is None:
            raise TimeoutError("no observation from the daemon within 10 s")
        self.obs = obs
        self.time = obs.stamp - self._t0

    def observation(self) -> PolicyObservation:
        assert self.obs is not None
        return self.obs

    def termination(self) -> str:
        obs = self.observation()
        if -obs.gravity[2] < UPRIGHT_MIN:
            return "fall"
        if not obs.running:
            status = self.robot.command("policy", op="status")
            return status.get("reason") or "the stream stopped"
        return ""

    def push(self, force: tuple[float, float, float], duration: float) -> None:
        self.sim.call("push", fx=force[0], fy=force[1], fz=force[2], duration=duration)

    def torso_height(self) -> float:
        return float("nan")

    def close(self) -> None:
        with contextlib.suppress(DarwinError):
            self.stream.stop()
        self.stream.close()
