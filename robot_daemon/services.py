"""The narrow views of the daemon that verb handlers get through ``MotionContext``.

A handler that starts ball play needs the camera's frames and nothing else of the daemon; the
``config`` verb needs the daemon's name and period. These are those views, so no handler
reaches into the daemon itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol


class FrameReader(Protocol):
    """One consumer's view of the camera: the next frame (BGR array) or None, then close."""

    def read(self) -> Any: ...
    def close(self) -> None: ...


class CameraFeed(Protocol):
    """The daemon's one camera owner, as its consumers see it."""

    spec: str  # the source it captures from ("sim", "0", "/dev/video0", …)

    def consumer(self) -> FrameReader:
        """A reader of the owner's frames; capture runs while any reader is open."""
        ...


@dataclass(frozen=True)
class DaemonInfo:
    """What the daemon runs as, for verbs that report it."""

    robot: str
    tick_ms: float
