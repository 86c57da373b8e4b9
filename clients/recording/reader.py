"""Read a recording back: ``read_recording(path)`` → :class:`Recording`.

The file is walked record by record (:mod:`clients.recording.scan`), so a recording whose
recorder was killed (no summary, a half-written last chunk) still yields every message up to the
last flush, and a damaged chunk costs only its own messages; ``Recording.truncated`` and
``Recording.notice`` say so, and ``darwin record recover`` makes such a file whole for every other
tool. Messages come from the msgpack channels (the exact bytes the robot published) and decode
with :mod:`schemas.messages` like live ones.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from mcap.records import Channel, Message, Metadata

from clients.recording.mcap_sink import RAW_ENCODING
from clients.recording.scan import NotMcapError, RecordScanner
from clients.robot import TOPICS
from schemas.errors import ProtocolError
from schemas.messages import Message as DarwinMessage
from schemas.messages import decode


@dataclass(frozen=True)
class RecordedMessage:
    """One message of a recording, as it was published, with when it arrived."""

    topic: str  # short name: joints, imu, status, events, camera, vision, world
    log_ns: int  # when the recorder received it (ns since the epoch)
    publish_ns: int  # the message's own stamp
    payload: bytes  # msgpack, exactly as published
    robot: str = ""  # whose it is (a recording of several robots holds each one's channels)

    def decode(self) -> DarwinMessage:
        return decode(self.payload, TOPICS[self.topic])


@dataclass
class Recording:
    """A recording read back: its messages and metadata, and what was wrong with the file."""

    path: str
    robot: str = ""
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    messages: list[RecordedMessage] = field(default_factory=list)
    truncated: bool = False  # the file ended early (recorder killed); messages are still valid
    problem: str = ""  # what ended the read early, or what was skipped
    notice: str = ""  # one line: what is wrong with the file and how to recover it

    def __repr__(self) -> str:
        span = f"{self.duration:.1f} s" if self.messages else "empty"
        tail = ", truncated" if self.truncated else ""
        n = len(self.messages)
        return f"<Recording {self.robot or '?'} {self.path}: {n} messages, {span}{tail}>"

    @property
    def start_ns(self) -> int:
        return self.messages[0].log_ns if self.messages else 0

    @property
    def end_ns(self) -> int:
        return self.messages[-1].log_ns if self.messages else 0

    @property
    def duration(self) -> float:
        return (self.end_ns - self.start_ns) / 1e9

    @property
    def robots(self) -> list[str]:
        """The robots whose messages the file holds (several with ``darwin record --robot A
        --robot B`` or ``--robot '*'``), sorted."""
        return sorted({m.robot for m in self.messages if m.robot})

    def only(self, robot: str) -> Recording:
        """The messages of one robot of a several-robot recording, as a recording of its own
        (what ``darwin replay --source`` plays)."""
        if robot not in self.robots:
            raise ValueError(
                f"{self.path} holds no robot {robot!r}; it holds {', '.join(self.robots) or 'none'}"
            )
        mine = [m for m in self.messages if m.robot == robot]
        return dataclasses.replace(self, robot=robot, messages=mine)

    def counts(self) -> dict[str, int]:
        return dict(Counter(m.topic for m in self.messages))

    def topic(self, name: str) -> list[RecordedMessage]:
        return [m for m in self.messages if m.topic == name]

    def decoded(self, name: str) -> Iterator[DarwinMessage]:
        """The messages of one topic, decoded; payloads that do not decode are skipped."""
        for m in self.messages:
            if m.topic == name:
                try:
                    yield m.decode()
                except ProtocolError:
                    continue

    def frame(self, name: str) -> Any:
        """One topic as a pandas DataFrame (the layout of :mod:`clients.dataframes`)."""
        from clients.dataframes import to_frame

        return to_frame(name, self.decoded(name))


log = logging.getLogger(__name__)


def read_recording(
    path: str | os.PathLike[str], *, on_notice: Callable[[str], object] | None = None
) -> Recording:
    """Load a recording made by :class:`clients.recording.Recorder` (or any MCAP file with
    ``msgpack`` channels carrying ``darwin_topic`` metadata).

    A truncated or damaged file is read as far as it is sound; its one-line ``notice`` (how to
    recover it) goes to ``on_notice`` (default: logged as a warning)."""
    path = os.fspath(path)
    rec = Recording(path)
    channels: dict[int, tuple[str, str]] = {}
    scanner = RecordScanner(path)
    try:
        for record in scanner:
            if isinstance(record, Channel):
                topic = record.metadata.get("darwin_topic", "")
                if record.message_encoding == RAW_ENCODING and topic in TOPICS:
                    channels[record.id] = (topic, record.metadata.get("robot", ""))
                    rec.robot = rec.robot or record.metadata.get("robot", "")
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is not None:
                    topic, robot = channel
                    rec.messages.append(
                        RecordedMessage(
                            topic, record.log_time, record.publish_time, record.data, robot
                        )
                    )
            elif isinstance(record, Metadata):
                rec.metadata[record.name] = dict(record.metadata)
                rec.robot = rec.robot or record.metadata.get("robot", "")
    except NotMcapError as exc:
        raise ProtocolError(f"{path} is not a readable MCAP recording ({exc})") from exc
    report = scanner.report
    if report.damaged:
        rec.truncated = report.truncated
        rec.problem = "; ".join([report.where(), *report.drops()])
        rec.notice = report.notice()
        (on_notice or log.warning)(rec.notice)
    rec.messages.sort(key=lambda m: m.log_ns)
    if not rec.robot and "darwin" in rec.metadata:
        rec.robot = rec.metadata["darwin"].get("robot", "")
    return rec


def read_session(
    paths: Iterable[str | os.PathLike[str]], *, on_notice: Callable[[str], object] | None = None
) -> Recording:
    """Several files (the segments of a split session, in any order) as one recording: messages
    merged in log-time order, the first file's metadata and robot, ``truncated`` and ``notice``
    from any file that has them."""
    parts = [read_recording(p, on_notice=on_notice) for p in paths]
    if not parts:
        raise ValueError("no recording files given")
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    rec = Recording(f"{first.path} (+{len(parts) - 1} more)", first.robot, dict(first.metadata))
    for part in parts:
        rec.messages.extend(part.messages)
        rec.robot = rec.robot or part.robot
        if part.notice:
            rec.truncated = rec.truncated or part.truncated
            rec.problem = "; ".join(filter(None, [rec.problem, part.problem]))
            rec.notice = rec.notice or part.notice
    rec.messages.sort(key=lambda m: m.log_ns)
    return rec

