"""Head tracking and search, once per vision frame (the framework's BallTracker and Head).

Tracking: the framework's Head::MoveTracking law — P and D terms on the angular error, each
*squared with its sign* (gentle on small errors, quick on large ones), added to the commanded
pan/tilt and clamped to the head's limits. Without the ball the last error is kept for
``lost_frames`` frames (the ball went out of view where it was heading); then the search
starts: pan sweeps of ±``search_pan_deg`` at each search tilt in turn. After
``sweeps_before_turn`` sweep cycles the tracker asks the body to turn in place (towards the side
the ball was last seen) while the sweeps go on; after ``search_timeout_s`` it gives up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from robot_daemon.motion.ball.settings import HeadSettings, TrackerSettings


@dataclass
class HeadCommand:
    """Where the ball tracker points the head this frame, and whether it is searching."""

    pan: float  # deg
    tilt: float  # deg
    searching: bool
    turn: float = 0.0  # deg of walking turn per step the search asks for (0 = stay)
    gave_up: bool = False


def _signed_square(v: float) -> float:
    return math.copysign(v * v, v)


class HeadTracker:
    def __init__(self, head: HeadSettings, tracker: TrackerSettings) -> None:
        self.head = head
        self.settings = tracker
        self.pan = head.home_pan_deg
        self.tilt = head.home_tilt_deg
        self.reset(self.pan, self.tilt, 0.0)

    def reset(self, pan: float, tilt: float, now: float) -> None:
        self.pan, self.tilt = pan, tilt
        self.err = (0.0, 0.0)
        self.lost = self.settings.lost_frames  # start by searching until the ball is seen
        self.last_side = 1.0  # +1: the ball was last seen to the left
        self._search_start: float | None = None
        self._sweep_leg = 0
        self._sweep_dir = 1.0

    @property
    def searching(self) -> bool:
        return self._search_start is not None

    def update(self, found: bool, pan_err: float, tilt_err: float, now: float, dt: float):
        """One vision frame: errors in degrees (positive = ball left / above), ``dt`` since
        the previous frame. Returns the :class:`HeadCommand`."""
        if found:
            self.lost = 0
            self._search_start = None
            self._track(pan_err, tilt_err)
            if abs(self.pan + pan_err) > 1.0:
                self.last_side = 1.0 if self.pan + pan_err > 0 else -1.0
            return HeadCommand(self.pan, self.tilt, searching=False)
        self.lost += 1
        if self.lost <= self.settings.lost_frames:
            self._track(*self.err)  # keep moving the way the ball went
            return HeadCommand(self.pan, self.tilt, searching=False)
        return self._search(now, dt)

    def _track(self, pan_err: float, tilt_err: float) -> None:
        h = self.head
        d_pan, d_tilt = pan_err - self.err[0], tilt_err - self.err[1]
        self.err = (pan_err, tilt_err)
        self.pan += _signed_square(pan_err * h.pan_p) + _signed_square(d_pan * h.pan_d)
        self.tilt += _signed_square(tilt_err * h.tilt_p) + _signed_square(d_tilt * h.tilt_d)
        self._clamp()

    def _clamp(self) -> None:
        h = self.head
        self.pan = max(-h.pan_limit_deg, min(h.pan_limit_deg, self.pan))
        self.tilt = max(h.tilt_min_deg, min(h.tilt_max_deg, self.tilt))

    def _search(self, now: float, dt: float) -> HeadCommand:
        s = self.settings
        if self._search_start is None:
            self._search_start = now
            self._sweep_leg = 0
            self._sweep_dir = self.last_side
            self.err = (0.0, 0.0)
        tilts = s.search_tilts_deg or (self.head.home_tilt_deg,)
        target_tilt = tilts[self._sweep_leg % len(tilts)]
        # Tilt goes to the sweep's level first, then the pan sweeps to the far side.
        step = s.search_speed_dps * dt
        self.tilt += max(-step, min(step, target_tilt - self.tilt))
        end = self._sweep_dir * s.search_pan_deg
        self.pan += max(-step, min(step, end - self.pan))
        if abs(self.pan - end) < 1e-6 and abs(self.tilt - target_tilt) < 1e-6:
            self._sweep_leg += 1
            self._sweep_dir = -self._sweep_dir
        self._clamp()
        cycles = self._sweep_leg // max(1, len(tilts))
        turn = self.last_side * s.search_turn_deg if cycles >= s.sweeps_before_turn else 0.0
        gave_up = now - self._search_start > s.search_timeout_s
        return HeadCommand(self.pan, self.tilt, searching=True, turn=turn, gave_up=gave_up)
