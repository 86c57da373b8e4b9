"""The JSON side of a recording: schemas derived from the message dataclasses, JSON payloads
that Foxglove and Python read, and the plain-text log lines."""

from __future__ import annotations

import base64
import dataclasses
import json
import math

import pytest

from clients.recording.jsonify import json_schema, schema_name, to_json
from clients.recording.segments import Sample
from clients.recording.text_sink import TextSink
from clients.robot import TOPICS
from schemas import SCHEMA_VERSION
from schemas.messages import (
    CameraFrame,
    Event,
    Imu,
    Joints,
    Message,
    Status,
    decode_dict,
    encode,
)

_JSON_TYPES = {"number", "integer", "string", "boolean", "array", "object", "null"}


def _types_in(schema: dict) -> set[str]:
    found = {schema["type"]} if "type" in schema else set()
    for sub in schema.get("anyOf", []):
        found |= _types_in(sub)
    if "items" in schema:
        found |= _types_in(schema["items"])
    for sub in schema.get("properties", {}).values():
        found |= _types_in(sub)
    return found


@pytest.mark.parametrize("cls", list(TOPICS.values()), ids=list(TOPICS))
def test_every_message_type_has_a_complete_schema(cls: type[Message]) -> None:
    schema = json_schema(cls)
    assert schema["type"] == "object"
    assert _types_in(schema) <= _JSON_TYPES
    if cls is not CameraFrame:
        assert schema_name(cls) == f"darwin.{cls.TYPE}"
        # Every dataclass field is described, none with an empty (unknown) schema.
        for f in dataclasses.fields(cls):
            assert schema["properties"][f.name], f.name


def test_imu_schema_types() -> None:
    props = json_schema(Imu)["properties"]
    assert props["gyro"] == {"type": "array", "items": {"type": "number"}}
    assert props["gyro_raw"]["items"] == {"type": "integer"}
    assert props["fall"] == {"type": "string"}


def test_optional_map_allows_null() -> None:
    lease = json_schema(Status)["properties"]["lease"]
    assert {"type": "null"} in lease["anyOf"]


def test_camera_frame_becomes_a_foxglove_compressed_image() -> None:
    frame = CameraFrame(jpeg=b"\xff\xd8\x00\xff\xd9", width=320, height=240, seq=7, stamp=12.25)
    out = json.loads(to_json(decode_dict(encode(frame)), CameraFrame))
    assert out == {
        "timestamp": {"sec": 12, "nsec": 250_000_000},
        "frame_id": "camera",
        "data": base64.b64encode(b"\xff\xd8\x00\xff\xd9").decode(),
        "format": "jpeg",
    }
    assert schema_name(CameraFrame) == "foxglove.CompressedImage"


def test_bytes_become_base64_and_nan_becomes_null() -> None:
    ev = Event(kind="fault", message="x", data={"raw": b"\x01\x02", "v": float("nan")})
    out = json.loads(to_json(decode_dict(encode(ev)), Event))
    assert out["data"] == {"raw": "AQI=", "v": None}
    assert out["type"] == "event" and out["v"] == SCHEMA_VERSION


def test_text_log_lines(tmp_path) -> None:
    path = tmp_path / "log.txt"
    sink = TextSink(str(path), "op1", {"imu": "darwin/op1/imu", "events": "darwin/op1/events"})
    imu = Imu(
        gyro=[0.1, 0.2, 0.3],
        accel=[0.0, 0.0, 9.81],
        gyro_raw=[1, 2, 3],
        accel_raw=[4, 5, 6],
        tick=42,
    )
    sink.write(Sample("imu", 1_500_000_000, encode(imu), decode_dict(encode(imu))))
    ev = Event(kind="lease", message="taken by notebook")
    sink.write(Sample("events", 2_000_000_000, encode(ev), decode_dict(encode(ev))))
    sink.write(Sample("events", 2_500_000_000, b"\xc1", None))
    sink.close()
    lines = path.read_text().splitlines()
    assert lines[0].startswith("# darwin-zenoh log of robot op1")
    assert lines[3] == (
        "1.500000\timu\ttick=42 gyro_x=0.1 gyro_y=0.2 gyro_z=0.3 "
        "accel_x=0 accel_y=0 accel_z=9.81 fall=none"
    )
    assert lines[4] == '2.000000\tevents\tkind=lease message="taken by notebook"'
    assert lines[5] == "2.500000\tevents\tundecodable payload of 1 bytes"


def test_text_log_shows_joints_in_degrees(tmp_path) -> None:
    """The wire carries radians; the text log, read by eye, shows degrees as the original's did."""
    path = tmp_path / "log.txt"
    sink = TextSink(str(path), "op1", {"joints": "darwin/op1/joints"})
    one = [[1], ["r_shoulder_pitch"], [math.radians(90.0)], [0.0], [0.0], [0.0], [40.0], [12.0]]
    joints = Joints(*one, torque_enabled=[True], online=[True], alarm=[0], tick=7)
    sink.write(Sample("joints", 1_000_000_000, encode(joints), decode_dict(encode(joints))))
    sink.close()
    assert path.read_text().splitlines()[-1] == "1.000000\tjoints\ttick=7 r_shoulder_pitch=90"
