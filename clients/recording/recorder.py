"""``Recorder``: subscribe to a robot's publications and write them to MCAP or a text log.

    >>> rec = Recorder(robot, "session.mcap", topics=["joints", "imu"]).start()
    >>> ...
    >>> stats = rec.stop()          # the file is complete and valid here

Zenoh callbacks only stamp the sample and queue it (never blocking: a full queue counts a drop);
one writer thread encodes and writes, and flushes every ``flush_interval`` seconds so a killed
recorder leaves a readable file.
"""

from __future__ import annotations

import logging
import os
import queue
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, Protocol, Self

import zenoh

from clients.recording.mcap_sink import McapSink
from clients.recording.text_sink import TextSink
from clients.robot import TOPICS, Commander
from schemas.errors import ClientError, ProtocolError
from schemas.keys import Keys
from schemas.messages import Message, decode_dict
from schemas.session import resolve

log = logging.getLogger(__name__)

FORMATS = ("mcap", "text")
DEFAULT_TOPICS: tuple[str, ...] = tuple(Keys().topics())


class Sink(Protocol):
    def write(
        self,
        topic: str,
        cls: type[Message],
        log_ns: int,
        payload: bytes,
        decoded: dict[str, Any] | None,
    ) -> None: ...

    def flush(self) -> None: ...

    def close(self) -> None: ...


@dataclass
class RecorderStats:
    path: str
    format: str
    robot: str
    counts: dict[str, int] = field(default_factory=dict)
    dropped: int = 0  # samples lost because the writer fell behind (queue full)
    undecodable: int = 0  # kept in the msgpack channel, missing from the JSON one
    duration: float = 0.0

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def summary(self) -> str:
        per = ", ".join(f"{t} {n}" for t, n in self.counts.items()) or "nothing"
        extra = f"; {self.dropped} dropped" if self.dropped else ""
        extra += f"; {self.undecodable} undecodable" if self.undecodable else ""
        return f"{self.path}: {self.total} messages in {self.duration:.1f} s ({per}){extra}"


def guess_format(path: str) -> str:
    return "text" if os.path.splitext(path)[1].lower() in {".txt", ".log", ".tsv"} else "mcap"


def check_topics(topics: Iterable[str] | None) -> list[str]:
    chosen = list(DEFAULT_TOPICS if topics is None else topics)
    unknown = [t for t in chosen if t not in TOPICS]
    if unknown or not chosen:
        raise ValueError(
            f"cannot record topic(s) {', '.join(map(repr, unknown)) or 'none'}; "
            f"choose among {', '.join(TOPICS)}"
        )
    return list(dict.fromkeys(chosen))


class Recorder:
    """Record ``topics`` of a robot into ``path``.

    ``source`` is a :class:`clients.robot.Robot` / ``Commander`` (its session and robot name are
    used) or a bare ``zenoh.Session`` (then pass ``robot``, else ``DARWIN_ROBOT`` or ``op1``).
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
        queue_size: int = 20_000,
    ) -> None:
        if isinstance(source, Commander):
            self._session = source.session
            name = robot or source.keys.robot
        else:
            self._session = source
            name = resolve(None, robot).robot
        self.keys = Keys(name)
        self.path = os.fspath(path)
        self.topics = check_topics(topics)
        self.format = format or guess_format(self.path)
        if self.format not in FORMATS:
            raise ValueError(f"unknown recording format {self.format!r}; use one of {FORMATS}")
        self.flush_interval = flush_interval
        self._queue: queue.Queue[tuple[str, int, bytes] | None] = queue.Queue(queue_size)
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

    def start(self) -> Self:
        if self._state != "new":
            raise ClientError(f"this Recorder is {self._state}; create a new one to record again")
        all_keys = self.keys.topics()
        keys = {t: all_keys[t] for t in self.topics}
        sink: Sink = (McapSink if self.format == "mcap" else TextSink)(
            self.path, self.keys.robot, keys
        )
        self._thread = threading.Thread(
            target=self._write_loop, args=(sink,), name="darwin-recorder", daemon=True
        )
        self._started = time.monotonic()
        self._state = "running"
        self._thread.start()
        for topic, key in keys.items():
            self._subs.append(
                self._session.declare_subscriber(key, lambda s, t=topic: self._on_sample(t, s))
            )
        return self

    def _on_sample(self, topic: str, sample: zenoh.Sample) -> None:
        payload = sample.payload.to_bytes()
        # Stamp and enqueue under one lock so the file is in log-time order across topics.
        with self._clock:
            try:
                self._queue.put_nowait((topic, time.time_ns(), payload))
            except queue.Full:
                self.stats.dropped += 1

    def _write_loop(self, sink: Sink) -> None:
        next_flush = time.monotonic() + self.flush_interval
        try:
            while True:
                try:
                    item = self._queue.get(timeout=max(0.0, next_flush - time.monotonic()))
                except queue.Empty:
                    item = ()  # type: ignore[assignment]
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

    def _write(self, sink: Sink, topic: str, log_ns: int, payload: bytes) -> None:
        cls = TOPICS[topic]
        decoded: dict[str, Any] | None
        try:
            decoded = decode_dict(payload)
            if decoded.get("type") != cls.TYPE:
                raise ProtocolError(f"expected {cls.TYPE!r}, got {decoded.get('type')!r}")
        except ProtocolError:
            decoded = None
            self.stats.undecodable += 1
        sink.write(topic, cls, log_ns, payload, decoded)
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
