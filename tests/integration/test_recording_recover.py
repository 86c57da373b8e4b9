"""A recorder killed with SIGKILL (real `darwin record` processes, real Zenoh on loopback): the
closed segments open with the stock `mcap` seeking reader, `darwin record recover` turns the
cut file into one it opens too, with every message the low-level record stream holds, and the
counts per topic sit between what was on disk before the kill and what a live subscriber got.
The recovered file replays like a clean one; a new recorder notices the cut file and keeps it."""

from __future__ import annotations

import os
import signal
import threading
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from clients.recording import read_recording
from clients.recording.scan import RecordScanner
from clients.recording.segments import existing_segments
from schemas.messages import CameraFrame, Joints, decode, encode
from schemas.session import free_tcp_port
from tests.fixtures.emulator import wait_until
from tests.fixtures.mcap import stock_counts, stream_counts
from tests.fixtures.system import run_darwin as darwin
from tests.integration.test_recording_mcap import (
    ROBOT,
    Source,
    darwin_record,
    imu_msg,
    joints_msg,
    started,
    subscribed,
)
from tests.integration.test_recording_replay import by_topic, darwin_replay, replay_to_the_end

TOPICS = ("joints", "imu", "camera")


@pytest.fixture
def source() -> Iterator[Source]:
    src = Source()
    yield src
    src.close()


class Publisher:
    """Publishes joints and IMU every tick and a ~12 kB camera frame every 10th, until stopped;
    a subscriber on the publisher's own session (so it misses nothing) counts what went out."""

    def __init__(self, src: Source) -> None:
        self.source = src
        self.live: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._subs = [
            src.session.declare_subscriber(src.keys.topics()[t], lambda s, t=t: self._count(t))
            for t in TOPICS
        ]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._rng = np.random.default_rng(7)

    def _count(self, topic: str) -> None:
        with self._lock:
            self.live[topic] += 1

    def counts(self) -> dict[str, int]:
        with self._lock:
            return dict(self.live)

    def _run(self) -> None:
        tick = 0
        while not self._stop.is_set():
            self.source.put("joints", encode(joints_msg(tick)))
            self.source.put("imu", encode(imu_msg(tick)))
            if tick % 10 == 0:
                jpeg = b"\xff\xd8" + self._rng.bytes(12_000) + b"\xff\xd9"
                frame = CameraFrame(jpeg=jpeg, width=320, height=240, seq=tick)
                self.source.put("camera", encode(frame))
            tick += 1
            self._stop.wait(0.004)  # pacing a publisher, not synchronising the test

    def start(self) -> Publisher:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()
        for sub in self._subs:
            sub.undeclare()


def on_disk(path: Path) -> dict[str, int]:
    """Messages per topic that read back from a file still being written."""
    try:
        return read_recording(path, on_notice=lambda line: None).counts()
    except Exception:
        return {}


def kill_mid_session(
    src: Source, path: Path, ready: Callable[[], dict[str, int]], *extra: str
) -> tuple[dict[str, int], dict[str, int]]:
    """Record while publishing; SIGKILL once ``ready(flushed)``; return (flushed before the kill,
    what the live subscriber got)."""
    proc = darwin_record(src.endpoint, path, "--topics", *TOPICS, *extra)
    publisher = None
    try:
        started(proc)
        subscribed(src, TOPICS)  # the recorder's subscriptions, before the live one exists
        publisher = Publisher(src).start()
        flushed: dict[str, int] = {}

        def enough() -> bool:
            nonlocal flushed
            flushed = ready()
            return bool(flushed)

        wait_until(enough, timeout=60, interval=0.05, what="flushed data on disk")
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.communicate(timeout=20)
        if publisher is not None:
            publisher.stop()
    assert proc.returncode == -signal.SIGKILL
    return flushed, publisher.counts()


def assert_between(kept: dict[str, int], flushed: dict[str, int], live: dict[str, int]) -> None:
    for topic in TOPICS:
        assert flushed.get(topic, 0) <= kept.get(topic, 0) <= live[topic], (
            topic,
            flushed,
            kept,
            live,
        )


def assert_no_gap(ticks: list[int]) -> None:
    # The recorder subscribed before the first publication: a prefix of the stream, no gap.
    assert ticks == list(range(len(ticks)))


def test_killed_recorder_recovers_into_a_file_every_reader_opens(
    source: Source, tmp_path: Path
) -> None:
    path = tmp_path / "killed.mcap"

    def ready() -> dict[str, int]:
        counts = on_disk(path)
        return counts if counts.get("joints", 0) >= 300 and counts.get("camera") else {}

    flushed, live = kill_mid_session(source, path, ready)
    with pytest.raises(Exception):  # noqa: B017 — the issue's symptom: the stock reader fails
        stock_counts(path)
    held = stream_counts(path)

    # A new recorder on the same name keeps the cut file and says how to recover it.
    before = path.read_bytes()
    again = darwin("record", "-o", str(path), "--connect", source.endpoint, "--robot", ROBOT)
    assert again.returncode == 2
    lines = again.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in again.stderr
    assert f"{path} is truncated at byte" in lines[0]
    assert f"run `darwin record recover {path}`" in lines[0]
    assert path.read_bytes() == before

    out = darwin("record", "recover", str(path))
    assert out.returncode == 0, out.stderr
    recovered = tmp_path / "killed.recovered.mcap"
    assert f"{recovered}: kept {sum(held.values())} messages" in out.stdout
    assert "last good record" in out.stdout or "between records" in out.stdout
    assert stock_counts(recovered) == held  # every message the low-level stream holds
    prefix = f"/darwin/{ROBOT}"
    for topic in TOPICS:
        key = "camera/jpeg" if topic == "camera" else topic
        assert f"  {prefix}/{key}/msgpack: {held[f'{prefix}/{key}/msgpack']}" in out.stdout

    back = read_recording(recovered)
    assert not back.truncated and not back.notice and back.robot == ROBOT
    assert back.metadata["darwin"]["robot"] == ROBOT
    assert "killed.mcap" in back.metadata["darwin.recovery"]["source"]
    assert_between(back.counts(), flushed, live)
    assert_no_gap([j.tick for j in back.decoded("joints")])
    with open(recovered, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.chunk_indexes
    assert all(ci.message_index_offsets for ci in summary.chunk_indexes)

    # Once recovered next to it, the cut file may be recorded over.
    again = darwin(
        "record",
        "-o",
        str(path),
        "--connect",
        source.endpoint,
        "--robot",
        ROBOT,
        "--duration",
        "0.3",
    )
    assert again.returncode == 0 and "truncated" not in again.stderr, again.stderr
    assert not read_recording(path).truncated


def test_killed_while_splitting_loses_only_the_open_segment_tail(
    source: Source, tmp_path: Path
) -> None:
    base = tmp_path / "seg.mcap"

    def ready() -> dict[str, int]:
        segments = existing_segments(str(base))
        if len(segments) < 4:  # three closed segments and an open one
            return {}
        return {"segments": len(segments)}

    _, live = kill_mid_session(source, base, ready, "--split-bytes", "65536")
    segments = [Path(p) for _, p in existing_segments(str(base))]
    assert len(segments) >= 4 and segments[0].name == "seg-0001.mcap"
    assert not base.exists()
    *closed, cut = segments
    kept: Counter[str] = Counter()
    sessions = set()
    for number, seg in enumerate(closed, start=1):
        assert stock_counts(seg) == stream_counts(seg)  # closed and indexed: nothing lost
        rec = read_recording(seg)
        assert not rec.truncated
        meta = rec.metadata["darwin"]
        assert meta["robot"] == ROBOT and meta["segment"] == str(number)
        sessions.add(meta["session"])
        kept.update(rec.counts())
    assert len(sessions) == 1  # one session, named in every segment

    out = darwin("record", "recover", str(cut), "-o", str(tmp_path / "last.mcap"))
    assert out.returncode == 0, out.stderr
    assert stock_counts(tmp_path / "last.mcap") == stream_counts(cut)
    last = read_recording(tmp_path / "last.mcap")
    assert last.metadata["darwin"]["segment"] == str(len(segments))
    kept.update(last.counts())
    for topic in TOPICS:
        assert kept[topic] <= live[topic]
    ticks = [
        decode(m.payload, Joints).tick
        for seg in [*closed, tmp_path / "last.mcap"]
        for m in read_recording(seg).topic("joints")
    ]
    assert_no_gap(ticks)

    # `darwin replay` takes the segments as one session.
    replay = darwin_replay(
        *map(str, closed),
        str(tmp_path / "last.mcap"),
        "--listen",
        f"tcp/127.0.0.1:{free_tcp_port()}",
    )
    try:
        assert replay.stderr is not None
        line = replay.stderr.readline()
    finally:
        replay.send_signal(signal.SIGTERM)
        replay.communicate(timeout=20)
    assert line.startswith(f"replaying {closed[0]} (+{len(closed)} more): {sum(kept.values())} ")

    # A new session keeps every segment and continues the numbering after the cut one.
    before = cut.read_bytes()
    again = darwin(
        "record",
        "-o",
        str(base),
        "--connect",
        source.endpoint,
        "--robot",
        ROBOT,
        "--split-seconds",
        "60",
        "--duration",
        "0.5",
    )
    assert again.returncode == 0, again.stderr
    notices = [line for line in again.stderr.splitlines() if "is truncated" in line]
    assert notices == [
        f"darwin record: {cut} is truncated at byte {_cut_at(cut)}: "
        f"run `darwin record recover {cut}`"
    ]
    assert cut.read_bytes() == before
    assert f"seg-{len(segments) + 1:04d}.mcap" in again.stderr


def _cut_at(path: Path) -> int:
    scanner = RecordScanner(path, light=True)
    for _ in scanner:
        pass
    rep = scanner.report
    return rep.size if rep.cut_at is None else rep.cut_at


def test_recovered_file_replays_like_a_clean_one(source: Source, tmp_path: Path) -> None:
    path = tmp_path / "cut.mcap"

    def ready() -> dict[str, int]:
        counts = on_disk(path)
        return counts if counts.get("joints", 0) >= 100 else {}

    kill_mid_session(source, path, ready)
    recovered = tmp_path / "cut.recovered.mcap"
    assert darwin("record", "recover", str(path)).returncode == 0
    rec = read_recording(recovered)
    expected = by_topic([(m.topic, m.payload) for m in rec.messages])

    got, err, _ = replay_to_the_end(
        [str(recovered)],
        "again",
        "10",
        len(rec.messages),
        lambda line: line.startswith("replaying") and "truncated" not in line,
        timeout=60,
    )
    assert "darwin record recover" not in err
    assert by_topic(got) == expected

    # The cut file itself still replays, and says how to recover it.
    cut = darwin_replay(str(path), "--listen", f"tcp/127.0.0.1:{free_tcp_port()}")
    try:
        assert cut.stderr is not None
        first, second = cut.stderr.readline(), cut.stderr.readline()
    finally:
        cut.send_signal(signal.SIGTERM)
        cut.communicate(timeout=20)
    assert first.startswith("replaying") and "(truncated file)" in first
    assert second.strip() == (
        f"darwin replay: {path} is truncated at byte {_cut_at(path)}: "
        f"run `darwin record recover {path}`"
    )
