"""``Recorder``: subscribe to a robot's publications and write them to MCAP or a text log.

    >>> rec = Recorder(robot, "session.mcap", topics=["joints", "imu"]).start()
    >>> ...
    >>> stats = rec.stop()          # the file is complete and valid here

Zenoh callbacks only stamp the sample and queue it (never blocking: a full queue counts a drop);
one writer thread encodes and writes, and flushes every ``flush_interval`` seconds so a killed
recorder loses at most that tail. ``split_seconds`` / ``split_bytes`` write the session as
numbered segments, each a closed, indexed file (:mod:`clients.recording.segments`). What is
subscribed and how it is encoded comes from a profile (:mod:`clients.recording.profile`).

Before writing, the recorder looks at its output place: a truncated MCAP file there (from a
killed recorder) is never overwritten, and ``notices`` holds one line per such file saying how to
recover it.
"""

from __future__ import annotations

import functools
import logging
import math
import os
import queue
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Self

import zenoh

from clients.commander import Commander
from clients.recording.mcap_sink import CHUNK_BYTES, McapSink
from clients.recording.profile import DARWIN, Profile, check_topics
from clients.recording.profiles import get_profile
from clients.recording.segments import (
    Sample,
    SegmentedSink,
    Sink,
    existing_segments,
    truncation_notice,
)
from clients.recording.text_sink import TextSink
from schemas.errors import ClientError
from schemas.keys import Keys, check_robot_name, every_robot, robot_of
from schemas.session import resolve

log = logging.getLogger(__name__)

FORMATS = ("mcap", "text")
DEFAULT_TOPICS: tuple[str, ...] = DARWIN.default_topics
FLUSH_RANGE = (0.02, 60.0)  # seconds: below, chunks get tiny; above, a kill loses too much
CHUNK_RANGE = (4 * 1024, 64 * 1024 * 1024)
MIN_SPLIT_BYTES = 64 * 1024


@dataclass
class RecorderStats:
    """What a recording wrote: its file(s), the messages per topic and robot, and what it lost."""

    path: str
    format: str
    robot: str
    counts: dict[str, int] = field(default_factory=dict)
    segments: list[str] = field(default_factory=list)  # the files written, when splitting
    dropped: int = 0  # samples lost because the writer fell behind (queue full)
    undecodable: int = 0  # kept in the msgpack channel, missing from the JSON one
    duration: float = 0.0
    by_robot: dict[str, int] = field(default_factory=dict)  # messages per robot (several robots)

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def summary(self) -> str:
        per = ", ".join(f"{t} {n}" for t, n in self.counts.items()) or "nothing"
        extra = f"; {self.dropped} dropped" if self.dropped else ""
        extra += f"; {self.undecodable} undecodable" if self.undecodable else ""
        if self.by_robot:
            per_robot = sorted(self.by_robot.items())
            extra += "; by robot: " + ", ".join(f"{r} {n}" for r, n in per_robot)
        where = self.path
        if self.segments:
            n = len(self.segments)
            where = f"{self.segments[0]}" + (
                f" … {self.segments[-1]} ({n} segments)" if n > 1 else " (1 segment)"
            )
        return f"{where}: {self.total} messages in {self.duration:.1f} s ({per}){extra}"


def guess_format(path: str) -> str:
    return "text" if os.path.splitext(path)[1].lower() in {".txt", ".log", ".tsv"} else "mcap"


def _check_number(name: str, value: float | None, low: float, high: float) -> None:
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ValueError(f"{name} {value!r} is not a number")
    if not low <= value <= high:
        raise ValueError(f"{name} {value:g} is outside [{low:g}, {high:g}]")


def check_options(
    flush_interval: float,
    chunk_bytes: int,
    split_seconds: float | None = None,
    split_bytes: int | None = None,
) -> None:
    """Raise ValueError naming the first option out of its range."""
    _check_number("flush interval", flush_interval, *FLUSH_RANGE)
    _check_number("chunk size", chunk_bytes, *CHUNK_RANGE)
    _check_number("split seconds", split_seconds, 1.0, 7 * 24 * 3600.0)
    _check_number("split bytes", split_bytes, MIN_SPLIT_BYTES, 2**50)


def check_robots(robots: Iterable[str] | None) -> list[str] | None:
    """The robots of a several-robot recording: names, or ``["*"]`` (every robot); None when
    not given. Raises ValueError naming a bad name."""
    if robots is None:
        return None
    names = list(dict.fromkeys(robots))
    if not names:
        raise ValueError("no robot to record: name one or more (or '*' for every robot)")
    if "*" in names:
        return ["*"]
    for name in names:
        check_robot_name(name)
    return names


class Recorder:
    """Record ``topics`` of a robot into ``path``.

    ``source`` is a :class:`clients.robot.Robot` / ``Commander`` (its session and robot name are
    used) or a bare ``zenoh.Session`` (then pass ``robot``, else ``DARWIN_ROBOT`` or ``op1``).
    ``split_seconds`` / ``split_bytes`` write numbered segments (``NAME-0001.mcap``…) instead
    of one file; ``flush_interval`` (s) and ``chunk_bytes`` bound what a kill can lose.
    ``profile`` is a :class:`Profile` or its name (``"darwin"``, ``"ros2"``: a ROS 2 bag).
    ``on_notice`` gets each one-line notice about a truncated file found in the output place
    (default: logged as a warning); they are also kept in ``notices``.
    ``robots`` records several robots into one file (``["op1", "op2"]``, or ``["*"]`` for every
    robot on the key space, those that appear later too): each robot's topics are channels of
    their own (``/darwin/op2/joints``…); the ``darwin`` profile only.
    """

    def __init__(
        self,
        source: Commander | zenoh.Session,
        path: str | os.PathLike[str],
        topics: Iterable[str] | None = None,
        *,
        robot: str | None = None,
        format: str | None = None,
        flush_interval: float = 0.5,
        chunk_bytes: int = CHUNK_BYTES,
        split_seconds: float | None = None,
        split_bytes: int | None = None,
        profile: Profile | str = DARWIN,
        queue_size: int = 20_000,
        on_notice: Callable[[str], object] | None = None,
        robots: Iterable[str] | None = None,
    ) -> None:
        self.robots = check_robots(robots)
        if isinstance(source, Commander):
            self._session = source.session
            name = robot or source.keys.robot
        else:
            self._session = source
            name = resolve(None, robot).robot
        if self.robots is not None:
            name = ",".join(self.robots)
        several = self.robots is not None and len(self.robots) > 1
        self.keys = every_robot() if several else Keys(self.robots[0] if self.robots else name)
        self.path = os.fspath(path)
        self.profile = get_profile(profile)
        if self.robots is not None and self.profile is not DARWIN:
            raise ValueError(
                f"several robots go into one file with the darwin profile only, not "
                f"{self.profile.name!r}: record each robot's {self.profile.name} bag on its own"
            )
        self.topics = check_topics(topics, self.profile)
        self.format = format or guess_format(self.path)
        if self.format not in FORMATS:
            raise ValueError(f"unknown recording format {self.format!r}; use one of {FORMATS}")
        check_options(flush_interval, chunk_bytes, split_seconds, split_bytes)
        self.flush_interval = flush_interval
        # A segment closes at the first chunk written past its size: keep chunks well below it.
        self.chunk_bytes = min(chunk_bytes, split_bytes // 4) if split_bytes else chunk_bytes
        self.split_seconds = split_seconds
        self.split_bytes = split_bytes
        self.notices: list[str] = []
        self._on_notice = on_notice or log.warning
        self._queue: queue.Queue[tuple[str, int, bytes, str | None] | None] = queue.Queue(
            queue_size
        )
        self._clock = threading.Lock()
        self._subs: list[Any] = []
        self._thread: threading.Thread | None = None
        self._started = 0.0
        self._state = "new"
        self.stats = RecorderStats(self.path, self.format, name, {t: 0 for t in self.topics})

    def __repr__(self) -> str:
        return f"<Recorder {self.keys.robot} → {self.path} ({self.format}): {self._state}, " + (
            f"{self.stats.total} messages>"
        )

    @property
    def running(self) -> bool:
        return self._state == "running"

    @property
    def splitting(self) -> bool:
        return self.split_seconds is not None or self.split_bytes is not None

    def _notice(self, line: str) -> None:
        self.notices.append(line)
        self._on_notice(line)

    def _check_output_place(self) -> int:
        """Report truncated files where this recording goes; return the first segment number.

        The single file is refused when it is truncated (recording there would destroy what it
        holds); segments continue after the highest one on disk, so none is ever overwritten.
        """
        segments = existing_segments(self.path)
        for _, seg in segments:
            if line := truncation_notice(seg):
                self._notice(line)
        single = truncation_notice(self.path)
        if single and not self.splitting:
            raise ClientError(f"{single}; it is kept: recover it or record to another name")
        if single:
            self._notice(single)
        if not self.splitting:
            return 0
        return (segments[-1][0] + 1) if segments else 1

    def _open_sink(self) -> Sink:
        # Several robots: the topics' key expressions for every robot (``darwin/*/joints``).
        keys = every_robot() if self.robots is not None else self.keys
        all_keys = {t: self.profile.key(keys, t) for t in self.topics}
        session = datetime.now(UTC).isoformat()
        robot = self.stats.robot

        def factory(path: str, metadata: dict[str, str]) -> Sink:
            if self.format == "text":
                return TextSink(path, robot, all_keys, metadata=metadata)
            return McapSink(
                path,
                robot,
                all_keys,
                profile=self.profile,
                chunk_bytes=self.chunk_bytes,
                metadata=metadata,
            )

        first = self._check_output_place()
        if not self.splitting:
            return factory(self.path, {})
        sink = SegmentedSink(
            self.path,
            factory,
            seconds=self.split_seconds,
            max_bytes=self.split_bytes,
            first=first,
            metadata={"session": session},
        )
        self.stats.segments = sink.paths  # grows as segments open
        return sink

    def start(self) -> Self:
        if self._state != "new":
            raise ClientError(f"this Recorder is {self._state}; create a new one to record again")
        # Per recording (the ros2 profile asks the daemon for the body here).
        self.profile = self.profile.bind(self._session, self.keys)
        sink = self._open_sink()
        self._thread = threading.Thread(
            target=self._write_loop, args=(sink,), name="darwin-recorder", daemon=True
        )
        self._started = time.monotonic()
        self._state = "running"
        self._thread.start()
        sources = [Keys(r) for r in self.robots] if self.robots is not None else [self.keys]
        for keys in sources:
            for topic in self.topics:
                key = self.profile.key(keys, topic)
                self._subs.append(
                    self._session.declare_subscriber(
                        key, functools.partial(self._on_sample, topic)
                    )
                )
        return self

    def _on_sample(self, topic: str, sample: zenoh.Sample) -> None:
        payload = sample.payload.to_bytes()
        robot = robot_of(str(sample.key_expr)) if self.robots is not None else None
        # Stamp and enqueue under one lock so the file is in log-time order across topics.
        with self._clock:
            try:
                self._queue.put_nowait((topic, time.time_ns(), payload, robot))
            except queue.Full:
                self.stats.dropped += 1

    def _write_loop(self, sink: Sink) -> None:
        next_flush = time.monotonic() + self.flush_interval
        try:
            while True:
                try:
                    item = self._queue.get(timeout=max(0.0, next_flush - time.monotonic()))
                except queue.Empty:
                    item = ()  # type: ignore[assignment]  # nothing came: time to flush
                if item is None:
                    break
                if item:
                    self._write(sink, *item)
                if time.monotonic() >= next_flush:
                    sink.flush()
                    next_flush = time.monotonic() + self.flush_interval
        except Exception:
            log.exception("recording to %s failed; the file holds what came before", self.path)
            self._state = "failed"
        finally:
            sink.close()

    def _write(
        self, sink: Sink, topic: str, log_ns: int, payload: bytes, robot: str | None
    ) -> None:
        decoded = self.profile.decode(topic, payload)
        if decoded is None:
            self.stats.undecodable += 1
        sink.write(Sample(topic, log_ns, payload, decoded, robot))
        if robot is not None:
            self.stats.by_robot[robot] = self.stats.by_robot.get(robot, 0) + 1
        self.stats.counts[topic] += 1

    def stop(self) -> RecorderStats:
        """Stop subscribing, write what is queued, close the file; return the figures."""
        if self._state not in {"running", "failed"}:
            return self.stats
        for sub in self._subs:
            try:
                sub.undeclare()
            except zenoh.ZError as exc:
                log.debug("undeclaring a recorder subscriber: %s", exc)
        self._subs.clear()
        if self._thread is not None:
            while self._thread.is_alive():
                try:
                    self._queue.put(None, timeout=0.5)
                    break
                except queue.Full:
                    continue  # the writer is draining; it may also have failed and exited
            self._thread.join()
        self.stats.duration = time.monotonic() - self._started
        if self._state == "running":
            self._state = "stopped"
        return self.stats

    def __enter__(self) -> Self:
        return self if self._state == "running" else self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
