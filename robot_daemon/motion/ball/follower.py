"""Walk to the ball and decide the kick, once per vision frame (the framework's BallFollower).

The head's pan and tilt (where the tracker points the camera) say where the ball is:

* ball outside ±``kick_pan_deg`` of pan: turn in place, up to ``fit_max_turn_deg``;
* inside, head above its bottom limit (or the ball not yet low in the image): step forward,
  ``follow_max_step_mm`` scaled by how high the head looks (at least ``follow_min_step_mm``),
  turning by pan;
* head at its bottom limit and the ball more than ``kick_top_deg`` below the image centre:
  stop; after ``kick_frames`` steady frames, kick with the foot on the ball's side.

The framework picks the foot from the head's pan alone. The tracker lags the ball by a few
degrees, so near the centre line the pan can still point left while the ball already lies
right of the robot, and the kick misses; the side here is the ball's bearing, pan plus the
ball's pan error in the image.

Commanded steps ramp towards their goals by ``unit_step_mm`` and ``unit_turn_deg`` per frame; a
stop is only asked when the goals and the ramped values are all zero.
"""

from __future__ import annotations

from dataclasses import dataclass

from robot_daemon.motion.ball.settings import FollowerSettings, HeadSettings
from schemas.units import DEG_PER_UNIT


@dataclass
class WalkCommand:
    """What the ball follower asks of the walk this frame: a step and a turn, a kick, or a stop."""

    walk: bool  # True: walking with (step, turn); False: stopped (or stopping)
    step: float = 0.0  # mm per step, forward
    turn: float = 0.0  # deg per step, positive = left
    kick: int = 0  # 0 none, +1 left foot, -1 right foot


class Follower:
    def __init__(self, follower: FollowerSettings, head: HeadSettings) -> None:
        self.s = follower
        self.head = head
        self.reset()

    def reset(self) -> None:
        self.step = 0.0
        self.turn = 0.0
        self.goal_step = 0.0
        self.goal_turn = 0.0
        self.kick_count = 0
        self.no_ball = 0
        self.walking = False

    def update(
        self, found: bool, tilt_err: float, pan: float, tilt: float, pan_err: float = 0.0
    ) -> WalkCommand:
        """One frame: ``tilt_err``/``pan_err`` where the ball is from the image centre (deg),
        ``pan``/``tilt`` the head's present angles (deg)."""
        s, h = self.s, self.head
        kick = 0
        if not found:
            self.kick_count = 0
            if self.no_ball > s.no_ball_frames:
                self.goal_step = self.goal_turn = 0.0
            else:
                self.no_ball += 1
        else:
            self.no_ball = 0
            pan_percent = pan / h.pan_limit_deg
            tilt_percent = abs((tilt - h.tilt_min_deg) / (h.tilt_max_deg - h.tilt_min_deg))
            if -s.kick_pan_deg < pan < s.kick_pan_deg:
                at_bottom = tilt <= h.tilt_min_deg + DEG_PER_UNIT  # the framework's slack: one unit
                if at_bottom and tilt_err < s.kick_top_deg:
                    self.goal_step = self.goal_turn = 0.0
                    if self.kick_count >= s.kick_frames:
                        self.step = self.turn = 0.0
                        kick = 1 if pan + pan_err > 0 else -1
                    self.kick_count += 1
                else:
                    self.kick_count = 0
                    self.goal_step = max(s.follow_max_step_mm * tilt_percent, s.follow_min_step_mm)
                    self.goal_turn = s.follow_max_turn_deg * pan_percent
            else:
                self.kick_count = 0
                self.goal_step = 0.0
                self.goal_turn = s.fit_max_turn_deg * pan_percent
        if self.goal_step == 0 and self.goal_turn == 0 and self.step == 0 and self.turn == 0:
            if self.walking:
                self.walking = False
            elif self.kick_count < s.kick_frames:
                self.kick_count += 1
            return WalkCommand(False, kick=kick if not self.walking else 0)
        if not self.walking:
            self.step = self.turn = 0.0
            self.kick_count = 0
            self.walking = True
            return WalkCommand(True, 0.0, 0.0)
        self.step = min(self.step + s.unit_step_mm, self.goal_step)
        if self.turn < self.goal_turn:
            self.turn = min(self.turn + s.unit_turn_deg, self.goal_turn)
        elif self.turn > self.goal_turn:
            self.turn = max(self.turn - s.unit_turn_deg, self.goal_turn)
        return WalkCommand(True, self.step, self.turn)
