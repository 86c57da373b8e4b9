"""`darwin record --ros2` on the real system (`darwin up` on the emulator): a ROS 2 bag in
rosbag2's MCAP layout, read back with an independent decoder (mcap-ros2-support builds its CDR
decoder from the schemas in the file, not from our types): header profile ``ros2``, ``ros2msg``
schemas, ``cdr`` channels named with the robot's namespace, joint_states with the URDF's joint
names and the daemon's positions, tf, the latched robot_description. Segments are bags each, and
a killed recorder's bag is recovered as a bag."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from ruamel.yaml import YAML

from clients.recording import Recorder
from clients.recording.scan import RecordScanner
from clients.recording.segments import existing_segments
from config.body import default_body
from schemas.messages import Joints
from schemas.session import free_tcp_port, open_client, open_server
from schemas.urdf import body_from_config_reply
from tests.fixtures.emulator import wait_until
from tests.fixtures.system import RunningSystem

TOPICS = "joints,imu,status"


def record(system: RunningSystem, path: Path, *extra: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "robot_daemon.launch.cli",
            "record",
            "--ros2",
            "-o",
            str(path),
            "--connect",
            system.endpoint,
            "--robot",
            system.robot,
            "--flush",
            "0.1",
            "--topics",
            TOPICS,
            *extra,
        ],
        stderr=subprocess.PIPE,
        text=True,
    )


def finish(proc: subprocess.Popen[str]) -> str:
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    return err


def decoded(path: Path | str) -> Iterator[tuple[str, Any]]:
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, _, msg in reader.iter_decoded_messages():
            yield channel.topic, msg


def check_layout(path: Path | str, ns: str) -> dict[str, str]:
    """Header, schemas and channels as rosbag2's MCAP storage writes them; topic → type."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
    assert summary is not None
    types = {}
    for ch in summary.channels.values():
        schema = summary.schemas[ch.schema_id]
        assert ch.message_encoding == "cdr", ch.topic
        assert schema.encoding == "ros2msg", schema.name
        assert schema.name.count("/msg/") == 1, schema.name
        assert ch.metadata["topic_type_hash"].startswith("RIHS01_"), ch.topic
        check_qos(ch.metadata["offered_qos_profiles"])
        assert ch.topic.startswith(f"{ns}/"), ch.topic
        types[ch.topic] = schema.name
    return types


def check_qos(text: str) -> None:
    """rosbag2 ≥ 9 (Jazzy on) reads a bag without its metadata record as its current version:
    the policies must be spelled as names (rmw's qos_string_conversions), durations sec/nsec."""
    (qos,) = YAML(typ="safe").load(text)
    assert qos["history"] == "keep_last" and qos["depth"] >= 1
    assert qos["reliability"] in {"reliable", "best_effort"}
    assert qos["durability"] in {"volatile", "transient_local"}
    assert qos["liveliness"] == "automatic"
    for d in ("deadline", "lifespan", "liveliness_lease_duration"):
        assert set(qos[d]) == {"sec", "nsec"}
    assert qos["avoid_ros_namespace_conventions"] is False


def stamp_of(msg: Any) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def test_ros2_bag_decodes_with_the_daemons_joints(
    robot_system: RunningSystem, tmp_path: Path
) -> None:
    path = tmp_path / "session.mcap"
    seen: list[Joints] = []
    with robot_system.robot_client(name="ros2 bag test") as robot:
        robot.wait_for("joints", timeout=15)
        body = body_from_config_reply(robot.config())
        witness = robot.subscribe("joints", seen.append)
        proc = record(robot_system, path, "--duration", "3")
        err = finish(proc)
        witness.close()
    assert "joints" in err and ".mcap" in err and "dropped" not in err

    ns = f"/{robot_system.robot}"
    types = check_layout(path, ns)
    assert types == {
        f"{ns}/joint_states": "sensor_msgs/msg/JointState",
        f"{ns}/tf": "tf2_msgs/msg/TFMessage",
        f"{ns}/tf_static": "tf2_msgs/msg/TFMessage",
        f"{ns}/robot_description": "std_msgs/msg/String",
        f"{ns}/imu/data": "sensor_msgs/msg/Imu",
        f"{ns}/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
    }

    names = [j.name for j in body.servo_joints()]
    assert len(names) == 20
    by_stamp = {round(j.stamp, 6): j for j in seen}
    matched = 0
    got: dict[str, list[Any]] = {}
    for topic, msg in decoded(path):
        got.setdefault(topic.removeprefix(ns), []).append(msg)
        if topic == f"{ns}/joint_states":
            assert sorted(msg.name) == sorted(names)
            live = by_stamp.get(round(stamp_of(msg), 6))
            if live is not None:
                matched += 1
                want = {body_name: None for body_name in names}
                by_id = dict(zip(live.id, live.position, strict=True))
                for j in body.servo_joints():
                    want[j.name] = by_id[j.servo_id]
                for n, p in zip(msg.name, msg.position, strict=True):
                    assert math.isclose(p, want[n], abs_tol=1e-12), n
    assert len(got["/joint_states"]) > 50
    # Every bag message the witness also saw carries the daemon's stamp and positions. Not a
    # share of the bag: a witness in a busy test process may miss some (the daemon drops
    # joints to a lagging subscriber rather than slow the others), the recorder none. A bag
    # stamped with its own receive times would match none at all.
    assert matched >= 50, (matched, len(got["/joint_states"]), len(seen))
    frames = {link.name for link in body.links}
    for tf in got["/tf"]:
        assert tf.transforms
        assert {t.child_frame_id for t in tf.transforms} <= frames
    (static,) = got["/tf_static"]
    assert static.transforms and {t.child_frame_id for t in static.transforms} <= frames
    (description,) = got["/robot_description"]
    assert "<robot" in description.data and all(n in description.data for n in names)
    imu = got["/imu/data"][-1]
    assert imu.orientation_covariance[8] > 1.0  # yaw unobserved, as the adapter says
    assert abs(imu.linear_acceleration.z) > 5.0  # gravity on a standing robot


def test_ros2_segments_and_recover_stay_bags(robot_system: RunningSystem, tmp_path: Path) -> None:
    ns = f"/{robot_system.robot}"
    # Segments: each a closed bag with the latched topics at its start.
    split = tmp_path / "split.mcap"
    finish(record(robot_system, split, "--split-seconds", "1", "--duration", "3.5"))
    segments = [p for _, p in existing_segments(str(split))]
    assert len(segments) >= 3
    for seg in segments:
        check_layout(seg, ns)
        topics = [t for t, _ in decoded(seg)]
        assert topics.count(f"{ns}/robot_description") == 1, seg
        assert topics.count(f"{ns}/tf_static") == 1, seg
        assert f"{ns}/joint_states" in topics, seg

    # A killed recorder: recover gives a bag with the same profile and schemas.
    cut = tmp_path / "cut.mcap"
    proc = record(robot_system, cut)
    try:

        def flushed_joint_states() -> bool:
            if not cut.exists():
                return False
            channels = {r.id: r.topic for r in RecordScanner(cut) if hasattr(r, "topic")}
            return f"{ns}/joint_states" in channels.values() and os.path.getsize(cut) > 30_000

        wait_until(flushed_joint_states, what="joint_states flushed to the bag")
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=20)
    out = tmp_path / "cut.recovered.mcap"
    fix = subprocess.run(
        [
            sys.executable,
            "-m",
            "robot_daemon.launch.cli",
            "record",
            "recover",
            str(cut),
            "-o",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert fix.returncode == 0, fix.stderr
    types = check_layout(out, ns)
    assert types[f"{ns}/joint_states"] == "sensor_msgs/msg/JointState"
    kept = [msg for t, msg in decoded(out) if t == f"{ns}/joint_states"]
    assert kept and all(len(m.name) == 20 for m in kept)


def test_notebook_recorder_takes_the_profile_by_name_and_falls_back_to_the_local_body(
    tmp_path: Path,
) -> None:
    """No daemon answers `config`: the bag still describes the robot, from the local config."""
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    path = tmp_path / "alone.mcap"
    with open_server([endpoint]), open_client(endpoint) as session:
        rec = Recorder(session, path, ["joints"], robot="nobody", profile="ros2").start()
        rec.stop()
    types = check_layout(path, "/nobody")
    assert types == {
        "/nobody/robot_description": "std_msgs/msg/String",
        "/nobody/tf_static": "tf2_msgs/msg/TFMessage",
    }
    (description,) = [m for t, m in decoded(path) if t == "/nobody/robot_description"]
    assert all(j.name in description.data for j in default_body().servo_joints())
    # darwin replay sends the project's msgpack channels, which a bag has not: it says so.
    replay = subprocess.run(
        [sys.executable, "-m", "robot_daemon.launch.cli", "replay", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert replay.returncode == 2
    assert "ROS 2 bag" in replay.stderr and "ros2 bag play" in replay.stderr
    assert "Traceback" not in replay.stderr


def test_unknown_profile_names_the_choices(tmp_path: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    with (
        open_server([endpoint]),
        open_client(endpoint) as session,
        pytest.raises(ValueError, match="darwin, ros2"),
    ):
        Recorder(session, tmp_path / "x.mcap", robot="r", profile="ros1")
