"""The head: pan/tilt within the configured limits, moved directly or tracking an angular
error with a PD law (hardware.md: pan ±70°, tilt −25..+40°, home (0°, +10°))."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from config.loader import refuse_unknown
from robot_daemon.frames import JointFrame
from robot_daemon.motion.interface import MotionModule
from schemas.kinematics import HEAD_PAN_ID, HEAD_TILT_ID


@dataclass(frozen=True)
class HeadLimits:
    """The head's range, home pose, speed and tracking gains (radians)."""

    pan_min: float = math.radians(-70)
    pan_max: float = math.radians(70)
    tilt_min: float = math.radians(-25)
    tilt_max: float = math.radians(40)
    home_pan: float = 0.0
    home_tilt: float = math.radians(10)
    speed: float = 3.0  # rad/s
    track_p: float = 0.35
    track_d: float = 0.05

    @classmethod
    def from_config(cls, section: dict[str, Any] | None) -> HeadLimits:
        s = section or {}
        refuse_unknown(s, _HEAD_KEYS, "head")
        d = cls()
        r = math.radians
        return cls(
            pan_min=r(s.get("pan_min_deg", math.degrees(d.pan_min))),
            pan_max=r(s.get("pan_max_deg", math.degrees(d.pan_max))),
            tilt_min=r(s.get("tilt_min_deg", math.degrees(d.tilt_min))),
            tilt_max=r(s.get("tilt_max_deg", math.degrees(d.tilt_max))),
            home_pan=r(s.get("home_pan_deg", 0.0)),
            home_tilt=r(s.get("home_tilt_deg", 10.0)),
            speed=float(s.get("speed", d.speed)),
            track_p=float(s.get("track_p", d.track_p)),
            track_d=float(s.get("track_d", d.track_d)),
        )


# The keys of [head] (config/motion.toml): angles in degrees there, radians here.
_HEAD_KEYS = (
    "pan_min_deg", "pan_max_deg", "tilt_min_deg", "tilt_max_deg",
    "home_pan_deg", "home_tilt_deg", "speed", "track_p", "track_d",
)


class HeadModule(MotionModule):
    name = "head"

    def __init__(self, limits: HeadLimits | None = None) -> None:
        super().__init__()
        self.limits = limits or HeadLimits()
        self.target: tuple[float, float] | None = None
        self.current: tuple[float, float] | None = None
        self.mode = "idle"  # idle | move | track
        self._last_error: tuple[float, float] | None = None

    def check(self, pan: float, tilt: float) -> None:
        """``ValueError`` naming the axis when a target is outside the head's limits."""
        lim = self.limits
        if not lim.pan_min - 1e-9 <= pan <= lim.pan_max + 1e-9:
            raise ValueError(
                f"pan {math.degrees(pan):.1f}° is outside "
                f"{math.degrees(lim.pan_min):.0f}°..{math.degrees(lim.pan_max):.0f}°"
            )
        if not lim.tilt_min - 1e-9 <= tilt <= lim.tilt_max + 1e-9:
            raise ValueError(
                f"tilt {math.degrees(tilt):.1f}° is outside "
                f"{math.degrees(lim.tilt_min):.0f}°..{math.degrees(lim.tilt_max):.0f}°"
            )

    def move(self, pan: float, tilt: float) -> tuple[float, float]:
        self.check(pan, tilt)
        self.claim({HEAD_PAN_ID, HEAD_TILT_ID})
        self.target, self.mode, self._last_error = (pan, tilt), "move", None
        return self.target

    def home(self) -> tuple[float, float]:
        return self.move(self.limits.home_pan, self.limits.home_tilt)

    def track(self, pan_error: float, tilt_error: float) -> tuple[float, float]:
        """One tracking update: the head turns to reduce the angular error (rad, positive =
        the target is left of / above the camera axis). Returns the new target, clamped."""
        self.claim({HEAD_PAN_ID, HEAD_TILT_ID})
        lim = self.limits
        base = self.current or self.target or (lim.home_pan, lim.home_tilt)
        last = self._last_error or (pan_error, tilt_error)
        pan = base[0] + lim.track_p * pan_error + lim.track_d * (pan_error - last[0])
        tilt = base[1] + lim.track_p * tilt_error + lim.track_d * (tilt_error - last[1])
        self._last_error = (pan_error, tilt_error)
        self.target = (
            min(lim.pan_max, max(lim.pan_min, pan)),
            min(lim.tilt_max, max(lim.tilt_min, tilt)),
        )
        self.mode = "track"
        return self.target

    def reached(self) -> bool:
        return self.target is None or self.current == self.target

    def step(self, frame: JointFrame) -> dict[int, float]:
        if self.target is None:
            return {}
        if self.current is None:
            self.current = (float(frame.position[HEAD_PAN_ID]), float(frame.position[HEAD_TILT_ID]))
        limit = self.limits.speed * frame.dt
        moved = []
        for cur, tgt in zip(self.current, self.target, strict=True):
            delta = tgt - cur
            moved.append(tgt if abs(delta) <= limit else cur + math.copysign(limit, delta))
        self.current = (moved[0], moved[1])
        return {HEAD_PAN_ID: moved[0], HEAD_TILT_ID: moved[1]}

    def on_released(self, ids: set[int]) -> None:
        if not self.owned():
            self.halt()

    def halt(self) -> None:
        self.target = self.current = None
        self.mode, self._last_error = "idle", None

    def stop(self) -> None:
        # The head is harmless: it stops where it is and keeps the joints.
        if self.current is not None:
            self.target = self.current

    def status(self) -> dict[str, Any]:
        def deg(v: tuple[float, float] | None) -> list[float] | None:
            return None if v is None else [round(math.degrees(a), 2) for a in v]

        return {
            "active": self.active,
            "mode": self.mode,
            "target_deg": deg(self.target),
            "current_deg": deg(self.current),
        }
