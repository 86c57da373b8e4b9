"""Messages the link posts to the app from Zenoh threads.

Telemetry messages replace an older queued one of the same topic (``can_replace``), so a 125 Hz
stream can never back up the screen: the app only ever sees the newest sample.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from textual.message import Message


class LinkState(StrEnum):
    IDLE = "idle"  # not asked to connect yet
    CONNECTING = "connecting"
    UNREACHABLE = "unreachable"  # no Zenoh session to the endpoint (retrying)
    NO_DAEMON = "no_daemon"  # session open, the daemon's liveliness token is absent
    CONNECTED = "connected"


class Telemetry(Message, bubble=False):
    """One sample of a robot stream, posted by the link: ``topic`` is the client topic it came
    on (``joints``, ``imu``, ``status``, ``vision``, ``camera``, ``events``; see
    ``clients.robot.TOPICS``) and ``sample`` its decoded message.

    A newer sample supersedes a queued older one of the same topic, except events: each event
    is a line in the log, so none is ever merged away.
    """

    def __init__(self, topic: str, sample: Any) -> None:
        super().__init__()
        self.topic = topic
        self.sample = sample

    def can_replace(self, message: Message) -> bool:
        return (
            self.topic != "events"
            and isinstance(message, Telemetry)
            and message.topic == self.topic
        )


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
