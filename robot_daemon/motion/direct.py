"""Direct joint control: the `joint` and `pose` verbs.

A `joint` target is approached at a bounded speed; a `pose` is interpolated over its duration
with a smooth (cosine) profile so every joint starts and ends at rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from robot_daemon.motion.interface import JointFrame, MotionModule


@dataclass
class _Move:
    start: float  # rad
    target: float  # rad
    t0: float  # s
    duration: float  # s; 0 → speed-limited approach
    speed: float  # rad/s, used when duration == 0
    current: float  # rad, the goal last written


class DirectModule(MotionModule):
    name = "direct"

    def __init__(self, default_speed: float = 2.0) -> None:
        super().__init__()
        self.default_speed = default_speed
        self._moves: dict[int, _Move] = {}
        self._pending: list[tuple[dict[int, float], float, float]] = []

    def set_joint(self, joint_id: int, target: float, speed: float | None = None) -> None:
        self._pending.append(({joint_id: target}, 0.0, speed or self.default_speed))
        self.claim({joint_id})

    def set_pose(self, targets: dict[int, float], duration: float) -> None:
        self._pending.append((dict(targets), duration, self.default_speed))
        self.claim(set(targets))

    def step(self, frame: JointFrame) -> dict[int, float]:
        for targets, duration, speed in self._pending:
            for j, tgt in targets.items():
                prev = self._moves.get(j)
                start = prev.current if prev else float(frame.position[j])
                self._moves[j] = _Move(start, tgt, frame.time, duration, speed, start)
        self._pending.clear()
        out: dict[int, float] = {}
        for j, m in self._moves.items():
            if m.duration > 0:
                s = min(1.0, (frame.time - m.t0) / m.duration)
                m.current = m.start + (m.target - m.start) * (1 - math.cos(math.pi * s)) / 2
            else:
                step = m.speed * frame.dt
                delta = m.target - m.current
                m.current = (
                    m.target if abs(delta) <= step else m.current + math.copysign(step, delta)
                )
            out[j] = m.current
        return out

    def on_released(self, ids: set[int]) -> None:
        for j in ids:
            self._moves.pop(j, None)

    def halt(self) -> None:
        self._moves.clear()
        self._pending.clear()

    def stop(self) -> None:
        self.halt()
        self.release()

    def moving(self) -> bool:
        return any(abs(m.current - m.target) > 1e-6 for m in self._moves.values())

    def status(self) -> dict[str, Any]:
        return {"active": self.active, "moving": self.moving(), "joints": sorted(self._moves)}
