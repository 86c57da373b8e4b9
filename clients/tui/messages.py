"""Messages the link posts to the app from Zenoh threads.

Telemetry messages replace an older queued one of the same kind (``can_replace``), so a 125 Hz
stream can never back up the screen: the app only ever sees the newest sample.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from textual.message import Message

from schemas.messages import BallDetection, CameraFrame, Event, Imu, Joints, Status


class LinkState(StrEnum):
    IDLE = "idle"  # not asked to connect yet
    CONNECTING = "connecting"
    UNREACHABLE = "unreachable"  # no Zenoh session to the endpoint (retrying)
    NO_DAEMON = "no_daemon"  # session open, the daemon's liveliness token is absent
    CONNECTED = "connected"


class Telemetry(Message, bubble=False):
    """Base of the stream messages: a newer one supersedes a queued older one."""

    def can_replace(self, message: Message) -> bool:
        return type(message) is type(self)


class JointsUpdate(Telemetry):
    def __init__(self, joints: Joints) -> None:
        super().__init__()
        self.joints = joints


class ImuUpdate(Telemetry):
    def __init__(self, imu: Imu) -> None:
        super().__init__()
        self.imu = imu


class StatusUpdate(Telemetry):
    def __init__(self, status: Status) -> None:
        super().__init__()
        self.status = status


class CameraUpdate(Telemetry):
    def __init__(self, frame: CameraFrame) -> None:
        super().__init__()
        self.frame = frame


class BallUpdate(Telemetry):
    def __init__(self, ball: BallDetection) -> None:
        super().__init__()
        self.ball = ball


class EventArrived(Message, bubble=False):
    """Events are never merged: each one is a line in the log."""

    def __init__(self, event: Event) -> None:
        super().__init__()
        self.event = event


@dataclass
class LinkInfo:
    state: LinkState
    endpoint: str
    robot: str
    detail: str = ""


class LinkChanged(Message, bubble=False):
    def __init__(self, info: LinkInfo) -> None:
        super().__init__()
        self.info = info
