"""Messages the link posts to the app from Zenoh threads.

The robot's streams do not come one message per sample: joints and IMU at 125 Hz each,
interleaved, never merged under ``can_replace`` (it only merges a sample with the next queued one
of the same topic), and a starved app (a loaded machine, the robot's own one-core computer) fell
behind for good, with the keys queued behind the backlog. The link keeps the samples
(clients/tui/link.py ``Inbox``) and posts one :class:`TelemetryReady` while none is waiting;
the app takes them all at once, so the more it is starved, the more it takes per message.
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


class VersionNotice(Message, bubble=False):
    """The daemon announced a version this client works with but is older than (``text``)."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.text = text


class TelemetryReady(Message, bubble=False):
    """The link's inbox has samples: the app takes them (``Link.take``)."""


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
    """The link's state, with the robot and endpoint it is about."""

    state: LinkState
    endpoint: str
    robot: str
    detail: str = ""


class LinkChanged(Message, bubble=False):
    def __init__(self, info: LinkInfo) -> None:
        super().__init__()
        self.info = info
