"""Splitting a long recording into segments, and checking the output place before writing.

With ``split_seconds`` and/or ``split_bytes``, ``NAME.mcap`` is written as ``NAME-0001.mcap``,
``NAME-0002.mcap``… (four digits, more past 9999). Each segment is a complete, indexed file with
the session's ``darwin`` metadata plus ``session`` (the session's start, shared by its segments)
and ``segment`` (its number); a segment closes at the first message past its time or size, so a
kill loses at most the open segment's unflushed tail. A new session continues the numbering
after the highest segment already there, so it never overwrites one.
"""

from __future__ import annotations

import os
import re
import time
from collections.abc import Callable
from typing import Any, NamedTuple, Protocol

from clients.recording.scan import NotMcapError, RecordScanner


class Sample(NamedTuple):
    """One received message, as the recorder hands it to a sink."""

    topic: str  # short name: joints, imu, status, events, camera, vision, world
    log_ns: int  # when the recorder received it (ns since the epoch)
    payload: bytes  # msgpack, exactly as published
    decoded: dict[str, Any] | None  # the payload as a map; None when it is not msgpack
    robot: str | None = None  # whose, when one file records several robots (None: the file's)


class Sink(Protocol):
    def write(self, sample: Sample) -> None: ...

    def flush(self) -> None: ...

    def close(self) -> None: ...

    @property
    def size(self) -> int: ...


# (path, extra metadata) → an open sink
SinkFactory = Callable[[str, dict[str, str]], Sink]


def segment_path(path: str, index: int) -> str:
    """``walk.mcap``, 3 → ``walk-0003.mcap``."""
    base, ext = os.path.splitext(path)
    return f"{base}-{index:04d}{ext}"


def existing_segments(path: str) -> list[tuple[int, str]]:
    """The segments of ``path`` already on disk, as (number, path), in order."""
    base, ext = os.path.splitext(path)
    folder = os.path.dirname(path) or "."
    pattern = re.compile(re.escape(os.path.basename(base)) + r"-(\d{4,})" + re.escape(ext) + "$")
    try:
        names = os.listdir(folder)
    except OSError:
        return []
    found = [
        (int(m.group(1)), os.path.join(os.path.dirname(path), n))
        for n in names
        if (m := pattern.match(n))
    ]
    return sorted(found)


def truncation_notice(path: str) -> str:
    """One line when ``path`` is an MCAP file that needs ``darwin record recover``; else ""
    (also when its recovered copy, made from it as it is now, is already there)."""
    from clients.recording.recover import recovered_copy

    if recovered_copy(path):
        return ""
    try:
        scanner = RecordScanner(path, light=True)
        for _ in scanner:
            pass
    except (NotMcapError, OSError):
        return ""  # not ours to judge (or gone): the caller decides whether to overwrite
    return scanner.report.notice()


class SegmentedSink:
    """A sink that closes its file and opens the next segment every ``seconds`` / ``bytes``.

    ``first`` is the number of the first segment. ``paths`` lists the segments written so far.
    """

    def __init__(
        self,
        path: str,
        factory: SinkFactory,
        *,
        seconds: float | None = None,
        max_bytes: int | None = None,
        first: int = 1,
        metadata: dict[str, str] | None = None,
    ) -> None:
        self._path = path
        self._factory = factory
        self._seconds = seconds
        self._bytes = max_bytes
        self._metadata = dict(metadata or {})
        self._index = first
        self.paths: list[str] = []
        self._sink = self._open()

    def _open(self) -> Sink:
        path = segment_path(self._path, self._index)
        sink = self._factory(path, {**self._metadata, "segment": str(self._index)})
        self.paths.append(path)
        self._opened = time.monotonic()
        self._wrote = False
        return sink

    def _due(self) -> bool:
        if not self._wrote:
            return False  # never leave an empty segment behind
        if self._seconds is not None and time.monotonic() - self._opened >= self._seconds:
            return True
        return self._bytes is not None and self._sink.size >= self._bytes

    def write(self, sample: Sample) -> None:
        if self._due():
            self._sink.close()
            self._index += 1
            self._sink = self._open()
        self._sink.write(sample)
        self._wrote = True

    def flush(self) -> None:
        self._sink.flush()

    @property
    def size(self) -> int:
        return self._sink.size

    def close(self) -> None:
        self._sink.close()


_UNITS = {"s": 1.0, "m": 60.0, "min": 60.0, "h": 3600.0}
_SIZES = {
    "b": 1,
    "kb": 1000,
    "mb": 1000**2,
    "gb": 1000**3,
    "kib": 1024,
    "mib": 1024**2,
    "gib": 1024**3,
}


def parse_split(text: str) -> tuple[float | None, int | None]:
    """``"60s"``, ``"10m"``, ``"50MB"``, ``"1h 2GB"`` → (seconds, bytes); "" → (None, None).

    What the TUI's split field takes. Raises ValueError naming the part it cannot read.
    """
    seconds: float | None = None
    size: int | None = None
    for part in text.replace(",", " ").split():
        m = re.fullmatch(r"(\d+(?:\.\d+)?)\s*([a-zA-Z]+)", part)
        unit = m.group(2).lower() if m else ""
        if m and unit in _UNITS:
            seconds = float(m.group(1)) * _UNITS[unit]
        elif m and unit in _SIZES:
            size = int(float(m.group(1)) * _SIZES[unit])
        else:
            raise ValueError(
                f"cannot read the split {part!r}: use a time (60s, 10m, 1h) and/or a size "
                "(50MB, 1GB)"
            )
    return seconds, size
