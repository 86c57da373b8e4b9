"""The original project's plain-text log (``darwin record --format text``): one line per
message, tab-separated ``time  topic  name=value …``, readable by eye, ``grep`` and
``pandas.read_csv(sep="\\t")``. Joint positions are in degrees and IMU values in SI units, as in
the original's log of accelerometer, gyroscope and motor positions.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from typing import IO, Any

from clients.recording.segments import Sample

_AXES = ("x", "y", "z")


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    text = str(value)
    return f'"{text}"' if (" " in text or "\t" in text or not text) else text


def _fields(topic: str, d: dict[str, Any]) -> list[tuple[str, Any]]:
    if topic == "joints":
        out: list[tuple[str, Any]] = [("tick", d.get("tick", 0))]
        degrees = [math.degrees(p) for p in d.get("position", [])]
        out += list(zip(d.get("name", []), degrees, strict=False))
        return out
    if topic == "imu":
        out = [("tick", d.get("tick", 0))]
        for field in ("gyro", "accel"):
            out += [(f"{field}_{a}", v) for a, v in zip(_AXES, d.get(field, []), strict=False)]
        return [*out, ("fall", d.get("fall", ""))]
    if topic == "camera":
        jpeg = d.get("jpeg", b"")
        return [(k, d.get(k)) for k in ("seq", "width", "height")] + [("jpeg_bytes", len(jpeg))]
    if topic == "status":
        lease = d.get("lease") or {}
        return [
            ("state", d.get("state", "")),
            ("lease", lease.get("name", "-")),
            ("voltage", d.get("voltage", 0.0)),
        ]
    if topic == "events":
        return [("kind", d.get("kind", "")), ("message", d.get("message", ""))]
    return [
        (k, v)
        for k, v in d.items()
        if k not in {"v", "type", "stamp"} and isinstance(v, int | float | str | bool)
    ]


class TextSink:
    def __init__(
        self,
        path: str,
        robot: str,
        topics: dict[str, str],
        *,
        metadata: dict[str, str] | None = None,
    ) -> None:
        self._file: IO[str] = open(path, "w", encoding="utf-8")  # noqa: SIM115 — close()
        started = datetime.now(UTC).isoformat()
        self._file.write(f"# darwin-zenoh log of robot {robot}, started {started}\n")
        if metadata:
            self._file.write(f"# {' '.join(f'{k}={v}' for k, v in metadata.items())}\n")
        self._file.write(f"# topics: {' '.join(topics)}\n")
        self._file.write("# time_s\ttopic\tfields (joint positions in degrees, IMU in SI units)\n")
        self._file.flush()

    @property
    def size(self) -> int:
        return self._file.tell()

    def write(self, sample: Sample) -> None:
        topic, log_ns, payload, decoded, robot = sample
        if robot is not None:
            topic = f"{robot}/{topic}"  # several robots in one log: each line says whose
        if decoded is None:
            body = f"undecodable payload of {len(payload)} bytes"
        else:
            body = " ".join(f"{k}={_fmt(v)}" for k, v in _fields(topic, decoded))
        self._file.write(f"{log_ns / 1e9:.6f}\t{topic}\t{body}\n")

    def flush(self) -> None:
        self._file.flush()

    def close(self) -> None:
        self._file.close()
