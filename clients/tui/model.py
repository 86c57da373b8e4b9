"""What the UI knows about the robot: the latest messages and short histories for the plots.

Touched only from the app's thread (the link posts messages; handlers call ``add_*``), so no
locks. ``versions`` tell the render timer which views have something new to draw.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from schemas.messages import BallDetection, CameraFrame, Event, Imu, Joints, Status

HISTORY = 4000  # samples kept per stream: > 30 s at the daemon's 125 Hz
EVENTS = 1000


@dataclass
class Edits:
    """What the user is building in the UI; kept here so it survives a language switch
    (which composes the screen again)."""

    manipulate: bool = False
    pose: dict[int, float] = field(default_factory=dict)  # rad, the pose being edited
    pose_base: dict[int, float] = field(default_factory=dict)  # what reset goes back to
    preview: bool = False  # the figure shows the edited pose instead of the robot
    choreography: list[dict[str, Any]] = field(default_factory=list)
    behaviours: list[dict[str, Any]] = field(default_factory=list)
    walk_params: dict[str, Any] = field(default_factory=dict)
    walk: tuple[float, float, float] = (0.0, 0.0, 0.0)  # commanded x m/s, y m/s, turn rad/s
    actions: Any = None  # the Actions tab's state (ActionsState, clients/tui/tabs/page_edit.py)


@dataclass
class Model:
    """The latest message of each stream, the operator's edits and the plots' histories."""

    joints: Joints | None = None
    imu: Imu | None = None
    status: Status | None = None
    ball: BallDetection | None = None
    frame: CameraFrame | None = None
    client_id: str = ""
    edits: Edits = field(default_factory=Edits)
    imu_hist: deque[tuple[float, tuple[float, ...], tuple[float, ...]]] = field(
        default_factory=lambda: deque(maxlen=HISTORY)
    )
    joint_hist: deque[tuple[float, tuple[float, ...]]] = field(
        default_factory=lambda: deque(maxlen=HISTORY)
    )
    events: deque[Event] = field(default_factory=lambda: deque(maxlen=EVENTS))
    versions: dict[str, int] = field(default_factory=dict)  # bumped on each change of a stream
    event_count: int = 0
    frame_times: deque[float] = field(default_factory=lambda: deque(maxlen=30))

    def add_joints(self, msg: Joints) -> None:
        self.joints = msg
        self.joint_hist.append((msg.stamp, tuple(map(math.degrees, msg.position))))
        self.bump("joints")

    def add_imu(self, msg: Imu) -> None:
        self.imu = msg
        self.imu_hist.append((msg.stamp, tuple(msg.accel), tuple(msg.gyro)))
        self.bump("imu")

    def add_status(self, msg: Status) -> None:
        self.status = msg
        self.bump("status")

    def add_ball(self, msg: BallDetection) -> None:
        self.ball = msg
        self.bump("camera")

    def add_frame(self, msg: CameraFrame) -> None:
        self.frame = msg
        self.frame_times.append(msg.stamp)
        self.bump("camera")

    def add_event(self, msg: Event) -> None:
        self.events.append(msg)
        self.event_count += 1
        self.bump("events")

    def events_since(self, count: int) -> list[Event]:
        """The events added after the ``event_count`` was ``count`` (those the log still holds)."""
        new = min(self.event_count - count, len(self.events))
        return list(self.events)[len(self.events) - new :] if new > 0 else []

    def add(self, topic: str, msg: Any) -> None:
        """Store a sample of the client topic ``topic`` (what the link posts as telemetry)."""
        _ADD[topic](self, msg)

    def bump(self, what: str) -> None:
        self.versions[what] = self.versions.get(what, 0) + 1

    def version(self, *what: str) -> int:
        """A number that changes whenever any of the streams ``what`` changes."""
        return sum(self.versions.get(w, 0) for w in what)

    # -- derived views -------------------------------------------------------------------------
    def fps(self) -> float:
        """Camera frames per second over the last frames (by their capture stamps)."""
        if len(self.frame_times) < 2:
            return 0.0
        span = self.frame_times[-1] - self.frame_times[0]
        return (len(self.frame_times) - 1) / span if span > 0 else 0.0

    def lease_holder(self) -> tuple[str, bool] | None:
        """``(name, is_me)`` of the lease holder, or None when the lease is free."""
        lease = self.status.lease if self.status else None
        if not lease:
            return None
        return str(lease.get("name") or lease.get("client") or "?"), (
            lease.get("client") == self.client_id
        )

    def loop_rate(self) -> tuple[float, int] | None:
        """``(Hz, overruns)`` of the daemon's motion loop, from ``status.loop``."""
        loop = self.status.loop if self.status else None
        if not loop:
            return None
        period = float(loop.get("period_p50_ms") or loop.get("tick_ms") or 0.0)
        hz = 1000.0 / period if period > 0 else 0.0
        return hz, int(loop.get("overruns", 0))

    def loop_overloaded(self) -> float | None:
        """The share of ticks that overran (%) while the daemon says its computer cannot keep
        the loop (``status.loop.overloaded``), else None."""
        loop = self.status.loop if self.status else None
        if not loop or not loop.get("overloaded"):
            return None
        return float(loop.get("overrun_pct", 0.0))

    def joint_index(self, joint_id: int) -> int | None:
        if self.joints is None or joint_id not in self.joints.id:
            return None
        return self.joints.id.index(joint_id)

    def positions_rad(self) -> dict[int, float]:
        if self.joints is None:
            return {}
        return dict(zip(self.joints.id, self.joints.position, strict=False))

    def goal_deg(self, joint_id: int) -> float | None:
        i = self.joint_index(joint_id)
        if i is None or self.joints is None:
            return None
        return math.degrees(self.joints.goal[i])


# client topic → how the model stores it
_ADD: dict[str, Callable[[Model, Any], None]] = {
    "joints": Model.add_joints,
    "imu": Model.add_imu,
    "status": Model.add_status,
    "vision": Model.add_ball,
    "camera": Model.add_frame,
    "events": Model.add_event,
}
