"""Reading recordings: files that are not MCAP, empty files and truncated files, and the
replay's input checks (pure: no Zenoh session is opened)."""

from __future__ import annotations

from pathlib import Path

import pytest

from clients.recording.mcap_sink import McapSink
from clients.recording.reader import read_recording
from clients.recording.replay import check_rate, default_robot_name
from clients.recording.segments import Sample
from schemas.errors import InvalidCommandError, ProtocolError
from schemas.messages import Imu, decode_dict, encode

KEYS = {"imu": "darwin/op1/imu", "events": "darwin/op1/events"}


def imu(tick: int) -> bytes:
    return encode(
        Imu(
            gyro=[0.0] * 3,
            accel=[0.0, 0.0, 9.81],
            gyro_raw=[0] * 3,
            accel_raw=[0] * 3,
            tick=tick,
            stamp=100.0 + tick,
        )
    )


def write(path: Path, n: int) -> bytes:
    """Write a recording; return the file as it was after the last flush, before closing."""
    sink = McapSink(str(path), "op1", KEYS)
    for i in range(n):
        p = imu(i)
        sink.write(Sample("imu", 1_000 + i, p, decode_dict(p)))
        if i == n // 2:
            sink.flush()
    sink.write(Sample("events", 5_000, b"not msgpack \xc1", None))
    sink.flush()
    flushed = path.read_bytes()
    sink.close()
    return flushed


def test_round_trip_keeps_bytes_and_order(tmp_path: Path) -> None:
    write(tmp_path / "a.mcap", 10)
    rec = read_recording(tmp_path / "a.mcap")
    assert rec.robot == "op1" and not rec.truncated
    assert rec.counts() == {"imu": 10, "events": 1}
    assert [m.payload for m in rec.topic("imu")] == [imu(i) for i in range(10)]
    assert [m.tick for m in rec.decoded("imu")] == list(range(10))
    assert list(rec.decoded("events")) == []  # kept raw, skipped when decoding
    assert rec.duration == pytest.approx(4_000 / 1e9)
    assert "op1" in repr(rec) and "11 messages" in repr(rec)


@pytest.mark.parametrize("cut", [1, 100, 700])
def test_cut_file_keeps_what_was_flushed(tmp_path: Path, cut: int) -> None:
    path = tmp_path / "cut.mcap"
    data = write(path, 40)
    path.write_bytes(data[: len(data) - cut])
    rec = read_recording(path)
    assert rec.truncated and rec.problem
    ticks = [m.tick for m in rec.decoded("imu")]
    assert ticks == list(range(len(ticks))) and len(ticks) >= 21


@pytest.mark.parametrize("content", [b"", b"hello world, not an mcap file", b"\x89MCAP0\r\n\x01"])
def test_not_a_recording_names_the_file(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "bad.mcap"
    path.write_bytes(content)
    with pytest.raises(ProtocolError, match=r"bad\.mcap is not a readable MCAP recording"):
        read_recording(path)


def test_missing_file() -> None:
    with pytest.raises(FileNotFoundError):
        read_recording("/nonexistent/x.mcap")


@pytest.mark.parametrize("bad", [0, -1, 1000.0, float("nan"), "fast", True])
def test_rate_checks_name_the_field(bad: object) -> None:
    with pytest.raises(InvalidCommandError) as info:
        check_rate(bad)
    assert info.value.field == "rate"


def test_default_replay_name(tmp_path: Path) -> None:
    write(tmp_path / "a.mcap", 1)
    assert default_robot_name(read_recording(tmp_path / "a.mcap")) == "op1-replay"
