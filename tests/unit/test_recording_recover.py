"""`darwin record recover` and the tolerant record scanner on files cut or damaged on purpose, and
segments written by the sink (no Zenoh session: files only; the CLI as a real process)."""

from __future__ import annotations

import struct
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from clients.recording.mcap_sink import McapSink
from clients.recording.reader import read_recording, read_session
from clients.recording.recorder import check_options
from clients.recording.recover import RecoverError, default_output, recover
from clients.recording.segments import (
    Sample,
    SegmentedSink,
    existing_segments,
    parse_split,
    segment_path,
)
from schemas.messages import Imu, decode, decode_dict, encode
from tests.fixtures.mcap import stock_counts, stream_counts
from tests.fixtures.system import run_darwin as darwin

KEYS = {"imu": "darwin/op1/imu"}
RAW = "/darwin/op1/imu/msgpack"


def imu(tick: int) -> bytes:
    return encode(
        Imu(
            gyro=[0.01 * tick, 0.0, 0.0],
            accel=[0.0, 0.0, 9.81],
            gyro_raw=[0] * 3,
            accel_raw=[0] * 3,
            tick=tick,
            stamp=100.0 + tick,
        )
    )


def write_flushed(path: Path, n: int = 190, every: int = 25) -> bytes:
    """A recording flushed every ``every`` messages; returns the bytes before it was closed."""
    sink = McapSink(str(path), "op1", KEYS)
    for i in range(n):
        p = imu(i)
        sink.write(Sample("imu", 1_000 + i, p, decode_dict(p)))
        if i % every == every - 1:
            sink.flush()
    flushed = path.read_bytes()
    sink.close()
    return flushed


def ticks(path: Path) -> list[int]:
    return [decode(m.payload, Imu).tick for m in read_recording(path).topic("imu")]


def chunks(data: bytes) -> list[tuple[int, int]]:
    """(offset, length) of every top-level chunk record."""
    pos, out = 8, []
    while pos + 9 <= len(data):
        opcode, length = data[pos], struct.unpack("<Q", data[pos + 1 : pos + 9])[0]
        if pos + 9 + length > len(data):
            break
        if opcode == 0x06:
            out.append((pos, length))
        pos += 9 + length
    return out


def test_every_cut_recovers_what_the_record_stream_holds(tmp_path: Path) -> None:
    data = write_flushed(tmp_path / "a.mcap")
    cut_file = tmp_path / "cut.mcap"
    kept_before = -1
    for cut in range(0, len(data) + 1, 97):
        cut_file.write_bytes(data[:cut])
        out = tmp_path / f"r{cut}.mcap"
        try:
            result = recover(cut_file, out)
        except RecoverError as exc:
            assert cut < 300, (cut, exc)  # only a file cut in its magic or header
            continue
        assert result.written and stock_counts(out) == stream_counts(cut_file), cut
        assert ticks(out) == list(range(len(ticks(out))))
        assert result.total >= kept_before  # a longer file never recovers less
        kept_before = result.total
    assert kept_before >= 2 * 175  # all but the last unflushed batch of the longest cut


def test_corrupt_chunk_in_the_middle_keeps_the_chunks_around_it(tmp_path: Path) -> None:
    data = bytearray(write_flushed(tmp_path / "a.mcap"))
    offset, length = chunks(bytes(data))[3]  # messages 75..99
    data[offset + 80 : offset + 100] = bytes(20)
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    proc = darwin("record", "recover", "bad.mcap", cwd=tmp_path)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    dropped = next(line for line in proc.stdout.splitlines() if line.startswith("dropped:"))
    assert "Chunk of" in dropped and f"at byte {offset}" in dropped
    assert f"25 messages of {RAW}" not in dropped and f"{RAW} 25" in dropped
    out = tmp_path / "bad.recovered.mcap"
    assert stock_counts(out)[RAW] == 150
    assert ticks(out) == [*range(75), *range(100, 175)]
    notice = read_recording(bad, on_notice=lambda line: None).notice
    assert notice.startswith(f"{bad} is truncated at byte ")
    assert f" and has unreadable parts (Chunk of {length} bytes at byte {offset} " in notice
    assert notice.endswith(f"run `darwin record recover {bad}`")


def test_a_broken_record_length_is_skipped_to_the_next_sound_chunk(tmp_path: Path) -> None:
    data = bytearray(write_flushed(tmp_path / "a.mcap"))
    offset, _ = chunks(bytes(data))[2]
    data[offset + 1 : offset + 9] = struct.pack("<Q", 1 << 40)
    bad = tmp_path / "len.mcap"
    bad.write_bytes(bytes(data))
    result = recover(bad)
    assert result.written
    assert any(f"at byte {offset}" in d and "next sound chunk" in d for d in result.dropped())
    kept = ticks(Path(result.output))
    assert kept[:50] == list(range(50)) and kept[-1] == 174 and 50 not in kept


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "empty.mcap is empty: nothing to recover"),
        (b"PK\x03\x04 a zip file", "empty.mcap is not an MCAP file"),
        (b"\x89MCAP0\r\n\x01\x20\x00", "empty.mcap is cut inside the MCAP header"),
        (b"\x89MC", "empty.mcap is cut inside the MCAP magic"),
    ],
)
def test_nothing_to_recover_is_one_line(tmp_path: Path, content: bytes, message: str) -> None:
    (tmp_path / "empty.mcap").write_bytes(content)
    proc = darwin("record", "recover", "empty.mcap", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and message in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "empty.recovered.mcap").exists()
    assert not list(tmp_path.glob("*.part"))


def test_outputs_are_never_overwritten_unasked(tmp_path: Path) -> None:
    data = write_flushed(tmp_path / "a.mcap")
    (tmp_path / "cut.mcap").write_bytes(data[:-50])
    (tmp_path / "taken.mcap").write_bytes(b"mine")
    proc = darwin("record", "recover", "missing.mcap", cwd=tmp_path)
    assert proc.returncode == 2 and "cannot read missing.mcap" in proc.stderr
    proc = darwin("record", "recover", "cut.mcap", "-o", "taken.mcap", cwd=tmp_path)
    assert proc.returncode == 2 and "taken.mcap exists; pass --force" in proc.stderr
    assert (tmp_path / "taken.mcap").read_bytes() == b"mine"
    proc = darwin("record", "recover", "cut.mcap", "-o", "cut.mcap", cwd=tmp_path)
    assert proc.returncode == 2 and "pass --in-place" in proc.stderr
    assert "Traceback" not in proc.stderr
    proc = darwin("record", "recover", "cut.mcap", "--in-place", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert stock_counts(tmp_path / "cut.mcap")[RAW] == 175

    # A complete file needs nothing.
    proc = darwin("record", "recover", "a.mcap", cwd=tmp_path)
    assert proc.returncode == 0 and "a.mcap: nothing to recover" in proc.stdout
    assert not (tmp_path / "a.recovered.mcap").exists()
    assert default_output("x/walk.mcap") == "x/walk.recovered.mcap"
    assert default_output("walk.bin") == "walk.bin.recovered.mcap"


def test_attachments_metadata_and_header_profile_survive(tmp_path: Path) -> None:
    path = tmp_path / "other.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="someone else")
        sid = w.register_schema("std_msgs/msg/String", "ros2msg", b"string data")
        cid = w.register_channel("/chatter", "cdr", sid)
        w.add_attachment(1, 2, "calibration.yaml", "text/yaml", b"k: 1\n")
        w.add_metadata("rosbag2", {"a": "b"})
        for i in range(10):
            w.add_message(cid, i, b"\x00\x01\x00\x00" + bytes([i]), i)
        w.flush()
        data = path.read_bytes()
    path.write_bytes(data[: len(data) - 3])
    result = recover(path)
    assert result.counts == {"/chatter": 10} and result.attachments == 1
    with open(result.output, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        assert [a.name for a in reader.iter_attachments()] == ["calibration.yaml"]
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        schema = next(iter(reader.get_summary().schemas.values()))
        assert [m.data[-1] for _, _, m in reader.iter_messages()] == list(range(10))
    assert meta["rosbag2"] == {"a": "b"} and "darwin.recovery" in meta
    assert schema.encoding == "ros2msg" and schema.data == b"string data"


def test_segments_are_closed_indexed_and_numbered(tmp_path: Path) -> None:
    base = str(tmp_path / "walk.mcap")

    def factory(path: str, metadata: dict[str, str]) -> McapSink:
        return McapSink(path, "op1", KEYS, chunk_bytes=4096, metadata=metadata)

    sink = SegmentedSink(base, factory, max_bytes=8_000, first=3, metadata={"session": "s1"})
    for i in range(400):
        p = imu(i)
        sink.write(Sample("imu", 1_000 + i, p, decode_dict(p)))
    sink.close()
    assert sink.paths[0] == segment_path(base, 3) == str(tmp_path / "walk-0003.mcap")
    assert [p for _, p in existing_segments(base)] == sink.paths and len(sink.paths) >= 3
    seen: list[int] = []
    for number, path in enumerate(sink.paths, start=3):
        rec = read_recording(path)
        assert not rec.truncated and stock_counts(Path(path))[RAW] == len(rec.topic("imu"))
        assert rec.metadata["darwin"]["segment"] == str(number)
        assert rec.metadata["darwin"]["session"] == "s1"
        seen += [decode(m.payload, Imu).tick for m in rec.topic("imu")]
    assert seen == list(range(400))
    assert not list(tmp_path.glob("*.part"))
    whole = read_session(reversed(sink.paths))  # one session again, whatever the order given
    assert [decode(m.payload, Imu).tick for m in whole.topic("imu")] == list(range(400))
    assert whole.robot == "op1" and not whole.truncated


def test_split_and_flush_options_are_checked() -> None:
    assert parse_split("") == (None, None)
    assert parse_split("10m 1GB") == (600.0, 1_000_000_000)
    assert parse_split("90s,512KiB") == (90.0, 512 * 1024)
    with pytest.raises(ValueError, match="cannot read the split '60'"):
        parse_split("60")
    check_options(0.5, 256 * 1024, 60.0, 10_000_000)
    with pytest.raises(ValueError, match="flush interval 0 is outside"):
        check_options(0, 256 * 1024)
    with pytest.raises(ValueError, match="split bytes 100 is outside"):
        check_options(0.5, 256 * 1024, None, 100)
    with pytest.raises(ValueError, match="split seconds nan is not a number"):
        check_options(0.5, 256 * 1024, float("nan"))


def test_bad_record_options_are_one_line(tmp_path: Path) -> None:
    proc = darwin("record", "-o", "x.mcap", "--split-seconds", "0", cwd=tmp_path)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip() == "darwin record: split seconds 0 is outside [1, 604800]"


def test_random_damage_never_breaks_recover(tmp_path: Path) -> None:
    write_flushed(tmp_path / "a.mcap")
    data = (tmp_path / "a.mcap").read_bytes()  # complete: summary, footer and all
    rng = np.random.default_rng(19)
    bad, out = tmp_path / "bad.mcap", tmp_path / "out.mcap"
    for _ in range(80):
        damaged = bytearray(data)
        at = int(rng.integers(0, len(data)))
        n = int(rng.integers(1, 9))
        damaged[at : at + n] = rng.bytes(n)
        if rng.random() < 0.3:
            damaged = damaged[: int(rng.integers(at, len(data) + 1))]
        bad.write_bytes(bytes(damaged))
        try:
            result = recover(bad, out, overwrite=True, always=True)
        except RecoverError:
            assert at < 300  # the magic or the header itself was hit
            continue
        assert stock_counts(out) == Counter(result.counts), at
        kept = ticks(out)
        assert kept == sorted(set(kept))  # what is kept is in order, never duplicated
