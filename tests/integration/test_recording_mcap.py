"""Recording over real Zenoh sessions on loopback: a peer publishes the robot's topics with the
project's message types, the recorder (in-process and as the `darwin record` process) writes
MCAP, and the `mcap` library reads it back."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader

from clients.recording import Recorder, read_recording
from config.loader import load_robot
from schemas.keys import Keys
from schemas.messages import CameraFrame, Event, Imu, Joints, Status, encode
from schemas.session import open_client, open_server
from schemas.versions import PROTOCOL_VERSION
from tests.fixtures.emulator import wait_until
from tests.fixtures.mcap import finished_file, summary_counts
from tests.fixtures.system import darwin_command, run_darwin

ROBOT = "rec1"


ROBOT_CONFIG = load_robot()


def joints_msg(tick: int) -> Joints:
    cfg = ROBOT_CONFIG
    n = len(cfg.ids)
    pos = [0.01 * tick + 0.1 * i for i in range(n)]
    return Joints(
        id=list(cfg.ids),
        name=list(cfg.names),
        position=pos,
        goal=pos,
        velocity=[0.0] * n,
        load=[0.0] * n,
        temperature=[40.0] * n,
        voltage=[12.0] * n,
        torque_enabled=[True] * n,
        online=[True] * n,
        alarm=[0] * n,
        tick=tick,
    )


def imu_msg(tick: int) -> Imu:
    return Imu(
        gyro=[0.01 * tick, 0.0, -0.5],
        accel=[0.0, 0.1, 9.81],
        gyro_raw=[512] * 3,
        accel_raw=[512, 520, 700],
        tick=tick,
    )


class Source:
    """A peer that publishes like the daemon, on a loopback port of its own."""

    def __init__(self) -> None:
        from schemas.session import free_tcp_port

        self.endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
        self.session = open_server([self.endpoint])
        self.keys = Keys(ROBOT)
        # BLOCK, not the daemon's DROP: the tests count every message sent, and a burst of
        # camera frames on a loaded host would otherwise be dropped at the source.
        self.pubs = {
            t: self.session.declare_publisher(k, congestion_control=zenoh.CongestionControl.BLOCK)
            for t, k in self.keys.topics().items()
        }
        self.sent: dict[str, list[bytes]] = {}

    def put(self, topic: str, payload: bytes) -> None:
        self.pubs[topic].put(payload)
        self.sent.setdefault(topic, []).append(payload)

    def burst(self, ticks: range, every: float = 0.0) -> None:
        for tick in ticks:
            self.put("joints", encode(joints_msg(tick)))
            self.put("imu", encode(imu_msg(tick)))
            if tick % 10 == 0:
                # Announced as a daemon of this version does, so a replay of it serves clients.
                status = Status(state="running", robot=ROBOT, voltage=12.1,
                                protocol=list(PROTOCOL_VERSION))
                self.put("status", encode(status))
            if tick % 25 == 0:
                self.put(
                    "camera",
                    encode(
                        CameraFrame(jpeg=b"\xff\xd8fake\xff\xd9", width=320, height=240, seq=tick)
                    ),
                )
            if every:
                time.sleep(every)  # pacing a publisher, not synchronising the test

    def close(self) -> None:
        self.session.close()


@pytest.fixture
def source() -> Iterator[Source]:
    src = Source()
    yield src
    src.close()


def subscribed(
    source: Source, topics: tuple[str, ...] = ("joints", "imu", "status", "camera", "events")
) -> None:
    """Block until the publisher sees a subscriber on every topic it will publish."""
    for topic in topics:
        pub = source.pubs[topic]
        wait_until(lambda p=pub: p.matching_status.matching, what=f"a {topic} subscriber")


def test_recorder_counts_schemas_and_order(source: Source, tmp_path: Path) -> None:
    path = tmp_path / "rec.mcap"
    with open_client(source.endpoint) as session:
        rec = Recorder(session, path, robot=ROBOT).start()
        subscribed(source)
        source.burst(range(200))
        source.put("events", encode(Event(kind="lease", message="taken by test")))
        source.put("imu", b"\x93garbage")  # a foreign publisher: kept raw, not in JSON
        wait_until(lambda: rec.stats.total == sum(map(len, source.sent.values())), what="all")
        stats = rec.stop()
    assert stats.undecodable == 1 and stats.dropped == 0

    summary, messages = finished_file(path)
    by_topic = summary_counts(summary)
    schemas = {s.name: json.loads(s.data) for s in summary.schemas.values()}
    json_msgs = [(c.topic, m) for c, m in messages if c.message_encoding == "json"]

    prefix = f"/darwin/{ROBOT}"
    assert by_topic[f"{prefix}/joints"] == 200
    assert by_topic[f"{prefix}/joints/msgpack"] == 200
    assert by_topic[f"{prefix}/imu"] == 200  # the garbage sample is not valid JSON material
    assert by_topic[f"{prefix}/imu/msgpack"] == 201
    assert by_topic[f"{prefix}/status/msgpack"] == 20
    assert by_topic[f"{prefix}/camera/jpeg"] == 8
    assert by_topic[f"{prefix}/events"] == 1
    assert schemas["foxglove.CompressedImage"]["properties"]["format"]["type"] == "string"
    assert schemas["darwin.joints"]["properties"]["position"]["items"]["type"] == "number"

    first_joints = json.loads(next(m.data for t, m in json_msgs if t == f"{prefix}/joints"))
    assert first_joints["name"] == list(load_robot().names) and first_joints["tick"] == 0
    first_image = json.loads(next(m.data for t, m in json_msgs if t == f"{prefix}/camera/jpeg"))
    assert first_image["format"] == "jpeg" and first_image["data"] == "/9hmYWtl/9k="

    back = read_recording(path)
    assert not back.truncated and back.robot == ROBOT
    assert [m.payload for m in back.topic("joints")] == source.sent["joints"]
    assert [m.payload for m in back.topic("imu")] == source.sent["imu"]
    log_times = [m.log_ns for m in back.messages]
    assert log_times == sorted(log_times)
    ticks = [j.tick for j in back.decoded("joints")]
    assert ticks == list(range(200))


def test_text_format_is_the_plain_log(source: Source, tmp_path: Path) -> None:
    path = tmp_path / "rec.txt"
    with open_client(source.endpoint) as session:
        rec = Recorder(session, path, ["joints", "imu"], robot=ROBOT).start()
        subscribed(source, ("joints", "imu"))
        source.burst(range(5))
        wait_until(lambda: rec.stats.total == 10, what="10 messages")
        rec.stop()
    lines = path.read_text().splitlines()
    body = [line.split("\t") for line in lines if not line.startswith("#")]
    assert len(body) == 10
    assert {b[1] for b in body} == {"joints", "imu"}
    imu = next(b for b in body if b[1] == "imu")
    assert "accel_z=9.81" in imu[2] and "fall=none" in imu[2]
    joints = next(b for b in body if b[1] == "joints")
    assert joints[2].startswith("tick=0 ") and f"{load_robot().names[0]}=" in joints[2]


def test_unknown_topic_is_refused_with_the_choices(tmp_path: Path) -> None:
    with open_server([]) as session, pytest.raises(ValueError, match="choose among joints"):
        Recorder(session, tmp_path / "x.mcap", ["joints", "elbows"], robot=ROBOT)


def darwin_record(endpoint: str, path: Path, *extra: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        darwin_command(
            "record",
            "-o",
            str(path),
            "--connect",
            endpoint,
            "--robot",
            ROBOT,
            "--flush",
            "0.1",
            *extra,
        ),
        stderr=subprocess.PIPE,
        text=True,
    )


def started(proc: subprocess.Popen[str]) -> None:
    assert proc.stderr is not None
    line = proc.stderr.readline()
    assert line.startswith("recording"), line


def recording_burst(source: Source, path: Path, joints: int) -> subprocess.Popen[str]:
    """`darwin record` to ``path``, running, with a burst of ``joints`` joint samples (and the
    other topics') flushed to disk. Killed if it gets no further."""
    proc = darwin_record(source.endpoint, path)
    try:
        started(proc)
        subscribed(source)
        source.burst(range(joints))
        wait_until(lambda: len(read_recording(path).topic("joints")) == joints, what="flush")
    except BaseException:
        proc.kill()
        proc.communicate(timeout=20)
        raise
    return proc


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_darwin_record_closes_a_valid_file_on_signal(
    source: Source, tmp_path: Path, sig: signal.Signals
) -> None:
    path = tmp_path / "sig.mcap"
    proc = recording_burst(source, path, 50)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    assert "joints 50" in err
    summary, _ = finished_file(path)
    assert summary.statistics is not None
    assert summary.statistics.message_count == 2 * (50 + 50 + 5 + 2)


def test_killed_recorder_leaves_a_readable_file(source: Source, tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    proc = recording_burst(source, path, 100)
    try:
        source.burst(range(100, 110))  # may or may not reach the disk before the kill
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.communicate(timeout=20)
    back = read_recording(path)
    assert back.truncated
    ticks = [j.tick for j in back.decoded("joints")]
    assert ticks[:100] == list(range(100))
    assert ticks == list(range(len(ticks)))

    # The library's own non-strict streaming reader gets the same messages up to the cut.
    seen = 0
    with open(path, "rb") as f, pytest.raises(McapError):
        for _, channel, _ in NonSeekingReader(f).iter_messages(log_time_order=False):
            seen += channel.topic == f"/darwin/{ROBOT}/joints/msgpack"
    assert seen == len(ticks)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["record", "-o", "x.mcap", "--topics", "joints,elbows"],
            "cannot record topic(s) 'elbows'",
        ),
        (
            ["record", "-o", "/nonexistent/dir/x.mcap", "--connect", "tcp/127.0.0.1:1"],
            "cannot write",
        ),
        (["replay", "garbage.mcap"], "not a readable MCAP recording"),
        (["replay", "missing.mcap"], "cannot read missing.mcap"),
    ],
)
def test_cli_bad_input_is_explained(tmp_path: Path, args: list[str], message: str) -> None:
    (tmp_path / "garbage.mcap").write_bytes(b"this is not mcap")
    proc = run_darwin(*args, cwd=tmp_path)
    assert proc.returncode in {1, 2}, proc.stderr
    assert message in proc.stderr
    assert "Traceback" not in proc.stderr
