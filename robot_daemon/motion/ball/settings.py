"""Ball play settings: the ``[ballplay]`` config section (config/ballplay.toml).

Angles stay in degrees and steps in mm here, as the framework's BallTracker/BallFollower use
them; the module converts at its edges (detections and joints are rad).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from config.loader import section_to


@dataclass(frozen=True)
class HeadSettings:
    """``[ballplay.head]``: the head's range, home and PD gains while it tracks the ball."""

    pan_limit_deg: float = 70.0
    tilt_min_deg: float = -25.0
    tilt_max_deg: float = 40.0
    home_pan_deg: float = 0.0
    home_tilt_deg: float = 10.0
    pan_p: float = 0.1
    pan_d: float = 0.22
    tilt_p: float = 0.1
    tilt_d: float = 0.22
    max_speed_dps: float = 240.0


@dataclass(frozen=True)
class TrackerSettings:
    """``[ballplay.tracker]``: when the ball counts as lost and how the head searches for it."""

    lost_frames: int = 15
    search_pan_deg: float = 65.0
    search_tilts_deg: tuple[float, ...] = (0.0, 25.0)
    search_speed_dps: float = 90.0
    sweeps_before_turn: int = 1
    search_turn_deg: float = 20.0
    search_timeout_s: float = 40.0


@dataclass(frozen=True)
class FollowerSettings:
    """``[ballplay.follower]``: how the robot walks to the ball and when and with which page it
    kicks."""

    kick_pan_deg: float = 30.0
    kick_top_deg: float = -5.0
    kick_frames: int = 10
    follow_max_step_mm: float = 30.0
    follow_min_step_mm: float = 5.0
    follow_max_turn_deg: float = 35.0
    fit_max_turn_deg: float = 35.0
    unit_step_mm: float = 0.3
    unit_turn_deg: float = 1.0
    no_ball_frames: int = 10
    right_kick_page: int = 12
    left_kick_page: int = 13
    kick_timeout_s: float = 6.0
    kick_settle_s: float = 0.0


@dataclass(frozen=True)
class BallPlaySettings:
    """The ``[ballplay]`` section: the ball's colour, the vision rate, the kicks, and the head,
    tracker and follower."""

    color: str = "red"
    vision_hz: float = 30.0
    kicks: int = 1
    head: HeadSettings = HeadSettings()
    tracker: TrackerSettings = TrackerSettings()
    follower: FollowerSettings = FollowerSettings()

    @classmethod
    def from_config(cls, ballplay: dict[str, Any]) -> BallPlaySettings:
        return section_to(cls, ballplay, "ballplay", skip=VISION_TABLES)


# Tables of [ballplay] that the ball finder reads (robot_daemon.vision.ball_finder).
VISION_TABLES = ("colors", "finder", "camera")
