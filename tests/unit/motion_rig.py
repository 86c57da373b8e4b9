"""A motion manager stepped without a daemon: synthetic frames at the daemon's tick, and
servos that reach every goal by the next tick (a perfect plant, so a test sees the motion the
modules ask for, not a servo model's)."""

from __future__ import annotations

import numpy as np

from robot_daemon.frames import JointFrame
from robot_daemon.motion.manager import MotionManager, Targets

DT = 0.008


class PerfectServos:
    def __init__(self, manager: MotionManager) -> None:
        self.manager = manager
        self.pos = np.zeros(21)
        self.tick = 0

    def frame(self) -> JointFrame:
        """The next tick's frame: every servo online and torqued, where it was last sent."""
        f = JointFrame(self.tick, self.tick * DT, DT, position=self.pos.copy())
        f.online[:] = True
        f.torque_enabled[:] = True
        return f

    def step(self, frame: JointFrame | None = None) -> Targets:
        """One tick of the manager on ``frame`` (default :meth:`frame`); its goals are reached."""
        out = self.manager.step(frame if frame is not None else self.frame())
        for j, g in out.goal.items():
            self.pos[j] = g
        self.tick += 1
        return out
