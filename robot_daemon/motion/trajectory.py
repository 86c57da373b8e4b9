"""A joint trajectory played inside the loop: timed points, linearly interpolated per tick.

What ros2_control's joint trajectory controller does for position-only points, done where the
timing is (the daemon's 8 ms loop), so a trajectory sent once plays the same over any network.
Point 0 is implicit: the joints' goals when the trajectory starts, at t = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Trajectory:
    """Timed positions for some servos, sampled by the motion loop at each tick."""

    ids: tuple[int, ...]  # servo ids, one per column
    times: np.ndarray  # (n,) s from the start, strictly increasing, the first > 0
    positions: np.ndarray  # (n, len(ids)) rad, already checked against the limits

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def sample(self, t: float, start: np.ndarray) -> np.ndarray:
        """The positions at ``t`` s, from ``start`` (the goals at t = 0) through every point."""
        if t >= self.times[-1]:
            return self.positions[-1]
        k = int(np.searchsorted(self.times, t, side="right"))
        t0, p0 = (0.0, start) if k == 0 else (float(self.times[k - 1]), self.positions[k - 1])
        s = (t - t0) / (float(self.times[k]) - t0)
        return p0 + (self.positions[k] - p0) * max(0.0, s)
