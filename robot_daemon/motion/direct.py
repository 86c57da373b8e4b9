"""Direct joint control: the `joint`, `pose` and `trajectory` verbs.

A `joint` target is approached at a bounded speed; a `pose` is interpolated over its duration
with a smooth (cosine) profile so every joint starts and ends at rest; a `trajectory` is played
point by point in the loop (:mod:`robot_daemon.motion.trajectory`) and its joints then hold its
last point. A new target for any joint of a playing trajectory ends the trajectory there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from robot_daemon.frames import JointFrame
from robot_daemon.motion.interface import MotionModule
from robot_daemon.motion.trajectory import Trajectory


@dataclass
class _Move:
    """One joint's move towards a target, in a given time or at a given speed."""

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
        self._new_trajectory: Trajectory | None = None
        # The playing trajectory, its start time and the goals it started from.
        self._trajectory: tuple[Trajectory, float, np.ndarray] | None = None

    def set_joint(self, joint_id: int, target: float, speed: float | None = None) -> None:
        self._pending.append(({joint_id: target}, 0.0, speed or self.default_speed))
        self.claim({joint_id})

    def set_pose(self, targets: dict[int, float], duration: float) -> None:
        self._pending.append((dict(targets), duration, self.default_speed))
        self.claim(set(targets))

    def set_trajectory(self, trajectory: Trajectory) -> None:
        self._new_trajectory = trajectory
        self.claim(set(trajectory.ids))

    def stop_trajectory(self) -> bool:
        """End the playing trajectory where it is (its joints hold); True if one was playing."""
        playing = self._trajectory is not None or self._new_trajectory is not None
        self._new_trajectory = None
        self._end_trajectory()
        return playing

    def _end_trajectory(self) -> None:
        if self._trajectory is not None:
            for j in self._trajectory[0].ids:
                if j in self._moves:
                    m = self._moves[j]
                    self._moves[j] = _Move(m.current, m.current, 0.0, 0.0, 0.0, m.current)
            self._trajectory = None

    def _start_trajectory(self, frame: JointFrame) -> None:
        traj, self._new_trajectory = self._new_trajectory, None
        assert traj is not None
        self._end_trajectory()
        start = np.array(
            [self._moves[j].current if j in self._moves else frame.start_of(j) for j in traj.ids]
        )
        self._trajectory = (traj, frame.time, start)
        for j, p in zip(traj.ids, start, strict=True):
            self._moves[j] = _Move(float(p), float(p), frame.time, 0.0, 0.0, float(p))

    def _play_trajectory(self, frame: JointFrame) -> None:
        assert self._trajectory is not None
        traj, t0, start = self._trajectory
        t = frame.time - t0
        for j, p in zip(traj.ids, traj.sample(t, start), strict=True):
            m = self._moves[j]
            m.current = m.target = float(p)
        if t >= traj.duration:
            self._trajectory = None  # done: its joints hold the last point

    def step(self, frame: JointFrame) -> dict[int, float]:
        if self._new_trajectory is not None:
            self._start_trajectory(frame)
        if self._trajectory is not None and any(
            j in self._trajectory[0].ids for targets, _, _ in self._pending for j in targets
        ):
            self._end_trajectory()
        for targets, duration, speed in self._pending:
            for j, tgt in targets.items():
                prev = self._moves.get(j)
                start = prev.current if prev else frame.start_of(j)  # the goal it holds
                self._moves[j] = _Move(start, tgt, frame.time, duration, speed, start)
        self._pending.clear()
        if self._trajectory is not None:
            self._play_trajectory(frame)
        playing = set(self._trajectory[0].ids) if self._trajectory is not None else set()
        out: dict[int, float] = {}
        for j, m in self._moves.items():
            if j in playing:
                pass
            elif m.duration > 0:
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
        if self._trajectory is not None and ids & set(self._trajectory[0].ids):
            self._trajectory = None  # another module took one of its joints: it cannot go on
        for j in ids:
            self._moves.pop(j, None)

    def on_limp(self, ids: set[int]) -> None:
        # Only what moves those joints stops: a trajectory through them ends where it is (its
        # other joints hold), the moves of the limp joints are dropped, the rest go on.
        if self._trajectory is not None and ids & set(self._trajectory[0].ids):
            self._end_trajectory()
        for j in ids:
            self._moves.pop(j, None)
        self.release(ids)

    def halt(self) -> None:
        self._moves.clear()
        self._pending.clear()
        self._new_trajectory = None
        self._trajectory = None

    def stop(self) -> None:
        self.halt()
        self.release()

    def moving(self) -> bool:
        return self._trajectory is not None or any(
            abs(m.current - m.target) > 1e-6 for m in self._moves.values()
        )

    def status(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "active": self.active, "moving": self.moving(), "joints": sorted(self._moves)
        }
        if self._trajectory is not None:
            traj, _, _ = self._trajectory
            out["trajectory"] = {"points": len(traj.times), "duration": traj.duration}
        return out
