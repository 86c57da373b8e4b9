"""Legacy messages: parsing every spec example, naming every bad field, and translation."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gateway.messages import (
    Led,
    MessageError,
    Monitor,
    Operate,
    Orchestrate,
    OrchestrateStop,
    Playball,
    PlayItem,
    TimeItem,
    Walk,
    error_message,
    parse_message,
)
from gateway.settings import WalkMapping, load_settings
from gateway.translate import (
    led_command,
    operate_command,
    orchestrate_stop_command,
    playball_command,
    walk_command,
)
from schemas.errors import ErrorCode
from tests.legacy_client import APPENDIX_A_CLIENT_EXAMPLES


def parse(text: str):
    return parse_message(json.loads(text))


def test_appendix_examples_parse() -> None:
    got = [parse(e) for e in APPENDIX_A_CLIENT_EXAMPLES]
    assert got == [
        Monitor({"accelerometer": False, "camera": False, "gyroscope": False, "motors": False}),
        Monitor({"accelerometer": True}),
        Operate(3, 27.0),
        Led("head", (182, 35, 28)),
        Orchestrate((PlayItem(9, 5), PlayItem(325, 1), TimeItem(20.0))),
        OrchestrateStop(),
        Walk(False, 10.0, 0.0, 0.0),
        Playball(start=False),  # decision: client status 1 = stop
    ]


@pytest.mark.parametrize(
    ("message", "code", "needle"),
    [
        ("[1,2]", ErrorCode.INVALID, "JSON object with one tag"),
        ("{}", ErrorCode.INVALID, "exactly one tag"),
        ('{"monitor":{},"walk":{}}', ErrorCode.INVALID, "exactly one tag"),
        ('{"fly":{}}', ErrorCode.UNKNOWN, "unknown message tag 'fly'"),
        ('{"monitor":{"lidar":1}}', ErrorCode.UNKNOWN, "unknown field 'lidar'"),
        ('{"monitor":{"motors":2}}', ErrorCode.OUT_OF_RANGE, "motors must be 0 or 1"),
        ('{"monitor":{"period":1}}', ErrorCode.OUT_OF_RANGE, "period=1 is outside 10..10000"),
        ('{"monitor":5}', ErrorCode.INVALID, "expected an object"),
        ('{"operate":{"all":0,"id":3}}', ErrorCode.INVALID, "missing field 'position'"),
        ('{"operate":{"all":0,"id":21,"position":0}}', ErrorCode.OUT_OF_RANGE, "id=21"),
        ('{"operate":{"all":0,"id":0,"position":0}}', ErrorCode.OUT_OF_RANGE, "id=0"),
        ('{"operate":{"all":0,"id":3,"position":361}}', ErrorCode.OUT_OF_RANGE, "position=361"),
        ('{"operate":{"all":0,"id":3,"position":"27"}}', ErrorCode.INVALID, "must be a number"),
        ('{"operate":{"all":0,"id":true,"position":2}}', ErrorCode.INVALID, "must be an integer"),
        ('{"operate":{"all":0,"id":2.5,"position":2}}', ErrorCode.INVALID, "must be an integer"),
        ('{"led":{"id":25,"ledcolor":[1,2,3]}}', ErrorCode.OUT_OF_RANGE, "26 (forehead) or 27"),
        ('{"led":{"id":26,"ledcolor":[1,2]}}', ErrorCode.INVALID, "[red, green, blue]"),
        ('{"led":{"id":26,"ledcolor":[1,2,256]}}', ErrorCode.OUT_OF_RANGE, "blue=256"),
        ('{"led":{"id":27}}', ErrorCode.INVALID, "missing field 'ledcolor'"),
        ('{"orchestrate":[]}', ErrorCode.INVALID, "list of behaviours is empty"),
        ('{"orchestrate":[{"page":0,"type":1}]}', ErrorCode.OUT_OF_RANGE, "item 0: page=0"),
        ('{"orchestrate":[{"page":1}]}', ErrorCode.INVALID, "item 0: missing field 'type'"),
        ('{"orchestrate":[{"page":1,"type":1},{"time":1}]}', ErrorCode.OUT_OF_RANGE, "item 1"),
        ('{"orchestrate":[3]}', ErrorCode.INVALID, "item 0: expected an object"),
        ('{"orchestrate":{"status":1}}', ErrorCode.INVALID, "server's 'started' reply"),
        ('{"orchestrate":{}}', ErrorCode.INVALID, "missing field 'status'"),
        ('{"orchestrate":"go"}', ErrorCode.INVALID, "expected a list"),
        ('{"walk":{"a":0,"stop":0,"x":10}}', ErrorCode.INVALID, "missing field 'y'"),
        ('{"walk":{"a":0,"stop":3,"x":10,"y":0}}', ErrorCode.OUT_OF_RANGE, "stop must be 0 or 1"),
        ('{"playball":{}}', ErrorCode.INVALID, "missing field 'status'"),
    ],
)
def test_bad_messages_name_the_problem(message: str, code: ErrorCode, needle: str) -> None:
    with pytest.raises(MessageError) as e:
        parse(message)
    assert e.value.code == code
    assert needle in e.value.message


def test_non_finite_numbers_are_refused() -> None:
    with pytest.raises(MessageError, match="finite"):
        parse_message({"walk": {"a": 0, "stop": 0, "x": math.inf, "y": 0}})


def test_error_message_shape() -> None:
    assert error_message(ErrorCode.BUSY, "held by x") == {
        "error": {"code": "busy", "message": "held by x"}
    }


def test_operate_converts_degrees_to_radians_at_servo_resolution() -> None:
    cmd = operate_command(Operate(3, 27.0), all_duration=1.0)
    assert cmd.verb == "joint" and cmd.fields["id"] == 3
    assert cmd.fields["position"] == pytest.approx(math.radians(27.0), abs=math.radians(0.09))
    assert cmd.needs_lease
    every = operate_command(Operate(None, -10.0), all_duration=2.0)
    assert every.verb == "pose" and every.fields["duration"] == 2.0
    assert sorted(map(int, every.fields["positions"])) == list(range(1, 21))


def test_walk_units_are_the_walking_engines_amplitudes() -> None:
    # The daemon's gait turns (X mm, Y mm, A deg) into SI at its period: the legacy numbers
    # must come back out of that conversion unchanged.
    from config.loader import load_section
    from robot_daemon.motion.walking.gait import amplitudes_from_si

    period = load_section("walking")["period_time"]
    cmd = walk_command(Walk(False, 10, -5, 7), load_settings().walk)
    x, y, a = amplitudes_from_si(cmd.fields["x"], cmd.fields["y"], cmd.fields["turn"], period)
    assert (x, y, a) == pytest.approx((10, -5, 7), rel=1e-4)


def test_led_walk_playball_orchestrate_translation_and_lease_needs() -> None:
    assert led_command(Led("eye", (1, 2, 3))).fields == {"eye": [1, 2, 3]}
    mapping = WalkMapping(x_mps_per_unit=0.01, y_mps_per_unit=0.02, a_radps_per_unit=0.1)
    start = walk_command(Walk(False, 10, -5, 2), mapping)
    assert start.fields == {"op": "start", "x": 0.1, "y": -0.1, "turn": 0.2}
    assert start.needs_lease
    stop = walk_command(Walk(True, 0, 0, 0), mapping)
    assert stop.fields == {"op": "stop"} and not stop.needs_lease
    assert playball_command(Playball(start=True)).fields == {"op": "start"}
    assert playball_command(Playball(start=True)).needs_lease
    assert not playball_command(Playball(start=False)).needs_lease
    assert not orchestrate_stop_command().needs_lease


json_leaf = st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=10)
json_any = st.recursive(
    json_leaf,
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=12), inner, max_size=5)
    ),
    max_leaves=15,
)
tags = st.sampled_from(["monitor", "operate", "led", "orchestrate", "walk", "playball", "x"])


@settings(max_examples=200, deadline=None)
@given(tag=tags, body=json_any)
def test_random_messages_parse_or_raise_a_message_error(tag: str, body: object) -> None:
    try:
        parse_message({tag: body})
    except MessageError as exc:
        assert exc.code in set(ErrorCode) and exc.message
