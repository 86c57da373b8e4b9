import math
import typing

import pytest

from config import load_robot
from config.loader import load_all
from robot_daemon.bus.state import cm730_status
from robot_daemon.motion.setup import build_manager
from schemas import units
from schemas.errors import ProtocolError
from schemas.keys import Keys
from schemas.messages import Event, Joints, LedsInfo, MotionInfo, decode, encode


def test_keys_carry_the_robot_name_and_reject_bad_names() -> None:
    k = Keys("op2")
    assert k.joints == "darwin/op2/joints"
    assert k.cmd("joint") == "darwin/op2/cmd/joint"
    with pytest.raises(ValueError, match="unknown command verb"):
        k.cmd("fly")
    with pytest.raises(ValueError, match="not valid"):
        Keys("a/b")


def test_message_round_trip_and_type_check() -> None:
    j = Joints(
        id=[1],
        name=["r_shoulder_pitch"],
        position=[0.5],
        goal=[0.5],
        velocity=[0.0],
        load=[0.0],
        temperature=[40.0],
        voltage=[12.0],
        torque_enabled=[True],
        online=[True],
        alarm=[0],
        tick=3,
    )
    assert decode(encode(j), Joints) == j
    with pytest.raises(ProtocolError, match="expected a 'event'"):
        decode(encode(j), Event)
    with pytest.raises(ProtocolError, match="msgpack"):
        decode(b"\xc1garbage")


def test_another_schema_version_is_refused_in_one_line_naming_both_and_the_fix() -> None:
    """A payload of the last major (1: joints in degrees too) is refused by every decoder the
    same way: both versions and the fix, one line."""
    import msgpack

    from schemas import SCHEMA_VERSION
    from schemas.errors import InvalidCommandError
    from schemas.policy import PolicyAction, decode_strict
    from schemas.query import decode_request

    old = SCHEMA_VERSION - 1
    cases = [
        (lambda p: decode(p), {"type": "joints"}, ProtocolError),
        (decode_request, {"client": "old"}, InvalidCommandError),
        (lambda p: decode_strict(p, PolicyAction), {"type": "policy_action"}, ProtocolError),
    ]
    for decoder, fields, error in cases:
        with pytest.raises(error) as caught:
            decoder(msgpack.packb({"v": old, **fields}))
        text = str(caught.value)
        assert f"schema version {old} not supported" in text, text
        assert f"speaks {SCHEMA_VERSION}" in text and "install the same version" in text, text
        assert "\n" not in text


def test_joints_carry_radians_only() -> None:
    from schemas.messages import Joints as J

    assert "position" in J.COLUMNS and not any("deg" in c for c in J.COLUMNS)


@pytest.mark.parametrize("raw", [0, 1024, 2048, 3000, 4095])
def test_position_conversions_round_trip(raw: int) -> None:
    assert units.rad_to_raw(units.raw_to_rad(raw)) == raw
    assert units.deg_to_raw(units.raw_to_deg(raw)) == raw
    assert units.raw_to_rad(2048) == 0.0
    assert math.isclose(units.raw_to_deg(2048 + 1024), 90.0)


def test_color_word_and_signed_words() -> None:
    assert units.color_word_to_rgb(units.rgb_to_color_word(255, 128, 8)) == (248, 128, 8)
    assert units.signed_11bit(0x400 | 10) == -10
    assert units.encode_signed_11bit(-10) == 0x400 | 10
    assert math.isclose(units.accel_raw_to_ms2(512), 0.0)


def test_robot_config_has_twenty_joints_with_limits() -> None:
    robot = load_robot()
    assert robot.ids == tuple(range(1, 21))
    assert robot.joint("r_knee").id == 13
    assert robot.joint(20).name == "head_tilt"
    with pytest.raises(KeyError, match="unknown joint"):
        robot.joint("tail")


def test_the_status_sub_maps_name_every_key_the_daemon_publishes() -> None:
    """``status.motion`` and ``status.leds`` are typed: a key a module adds or drops without
    its type in schemas.messages fails here (clients read the types, not the daemon)."""
    motion = build_manager(load_robot(), load_all()).status()
    types = typing.get_type_hints(MotionInfo)
    assert set(motion) == set(types)
    for name, value in motion.items():
        if typing.is_typeddict(types[name]):
            assert set(value) == set(typing.get_type_hints(types[name])), name
    leds = cm730_status(bytes(range(1, 80)))["leds"]
    assert set(leds) == set(typing.get_type_hints(LedsInfo))
