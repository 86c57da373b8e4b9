"""Choreographies, the behaviour library and the motion verbs' handlers, stepped without a
daemon (the bus is the one fake: it records LED writes)."""

from __future__ import annotations

import math
from typing import Any

import pytest

from config.loader import load_all, load_robot
from robot_daemon.arbiter.registry import REGISTRY, MotionContext, Reject, Request
from robot_daemon.arbiter.verbs import load_all as load_verbs
from robot_daemon.motion.behaviours import BehaviourError, BehaviourLibrary
from robot_daemon.motion.setup import build_manager
from tests.unit.motion_rig import PerfectServos


class RecordingBus:
    def __init__(self) -> None:
        self.leds: list[tuple[int | None, int | None, int | None]] = []

    def set_leds(self, head: int | None, eye: int | None, panel: int | None) -> None:
        self.leds.append((head, eye, panel))

    def set_torque(self, ids: list[int], enable: bool) -> None: ...
    def read_registers(self, dxl_id: int, address: int, length: int) -> bytes:
        return bytes(length)

    def write_registers(self, dxl_id: int, address: int, data: bytes) -> None: ...


class Rig(PerfectServos):
    def __init__(self) -> None:
        load_verbs()
        self.robot = load_robot()
        self.settings = load_all()
        super().__init__(build_manager(self.robot, self.settings))
        self.bus = RecordingBus()
        self.events: list[tuple[str, str, dict[str, Any]]] = []

    def call(self, verb: str, **fields: Any) -> dict[str, Any]:
        ctx = MotionContext(
            self.robot,
            self.manager,
            self.bus,
            self.settings,
            None,
            lambda k, m, **d: self.events.append((k, m, d)),
        )
        return REGISTRY[verb](Request(verb, "c1", "tester", fields), ctx)

    def run(self, ticks: int) -> None:
        for _ in range(ticks):
            self.step()
            self.events += self.manager.drain_events()

    def choreo_events(self) -> list[tuple[str, Any]]:
        return [(d["state"], d.get("index")) for k, _, d in self.events if k == "choreography"]


def test_items_play_in_order_with_start_and_finish_events_and_leds() -> None:
    rig = Rig()
    applied = rig.call(
        "choreography",
        op="play",
        items=[
            {"behaviour": "eyes green"},
            {"kind": "pause", "duration": 0.2},
            {"behaviour": "walk forward", "duration": 0.8},
            {"page": 23},
            {"behaviour": "say hello"},
        ],
    )
    assert [i["kind"] for i in applied["items"]] == ["led", "pause", "walk", "action", "sound"]
    for _ in range(2000):
        rig.run(10)
        if not rig.manager.module("choreography").playing:
            break
    states = rig.choreo_events()
    assert states[0] == ("started", None) and states[-1] == ("finished", 5)
    assert states[1:-1] == [(s, i) for i in range(5) for s in ("item_started", "item_finished")]
    assert rig.bus.leds == [(None, 0b1111100000, None)]  # green eye word, head untouched
    walk_states = [d["state"] for k, _, d in rig.events if k == "walk"]
    assert walk_states == ["started", "stopped"]
    assert any(k == "sound" and d["say"] == "Hello" for k, _, d in rig.events)
    status = rig.manager.status()["choreography"]
    assert status["last_result"] == "finished" and not status["playing"]


def test_stop_finishes_the_walk_step_and_skips_the_rest() -> None:
    rig = Rig()
    rig.call(
        "choreography",
        op="play",
        items=[
            {"behaviour": 100, "duration": 30.0},
            {"page": 24},
            {"page": 60},
        ],
    )
    rig.run(150)
    assert rig.manager.module("walking").running
    rig.call("choreography", op="stop")
    rig.run(200)
    assert not rig.manager.module("walking").running
    assert rig.choreo_events()[-1][0] == "stopped"
    assert [i for s, i in rig.choreo_events() if s == "item_started"] == [0]
    assert not rig.manager.module("action").playing


def test_stop_all_on_lease_loss_aborts_the_list_and_stops_walking() -> None:
    rig = Rig()
    rig.call("choreography", op="play", items=[{"behaviour": 100}, {"behaviour": 101}])
    rig.run(120)
    rig.manager.stop_all()
    rig.run(200)
    assert not rig.manager.module("walking").running
    assert rig.choreo_events()[-1][0] == "stopped"


def test_bad_items_are_refused_before_anything_moves() -> None:
    rig = Rig()
    cases = [
        ([{"behaviour": 9999}], "behaviour"),
        ([{"page": 200}], "page"),
        ([{"behaviour": 100, "speed": 3}], "speed"),
        ([{"kind": "walk", "x": 0.1}], "duration"),
        ([{"kind": "walk", "x": 3.0, "duration": 1}], "x"),
        ([{"kind": "led", "eye": [300, 0, 0]}], "eye"),
        ([{"kind": "head", "pan": 3.0}], "pan"),
        ([{"page": 9, "type": 42}], "type"),
        ([], "items"),
    ]
    for items, field in cases:
        with pytest.raises(Reject) as err:
            rig.call("choreography", op="play", items=items)
        assert err.value.field == field, (items, err.value.message)
    assert not rig.manager.module("choreography").playing


def test_legacy_orchestrate_items_follow_the_type_table() -> None:
    rig = Rig()
    applied = rig.call(
        "choreography",
        op="play",
        items=[
            {"page": 9, "type": 1},
            {"page": 100, "type": 2},
            {"time": 4},
            {"page": 301, "type": 5},
            {"time": 2},
        ],
    )
    kinds = [(i["kind"], i.get("page"), i.get("duration")) for i in applied["items"]]
    assert kinds == [
        ("action", 9, None),
        ("walk", None, 4.0),
        ("action", 4, None),
        ("walk", None, 2.0),
    ]
    lib = BehaviourLibrary(load_all()["behaviours"])
    with pytest.raises(BehaviourError, match="is a walk, not a sound"):
        lib.legacy_item(100, 3)
    assert lib.get("obrigado").id == 301


def test_motion_verbs_check_fields_and_report_what_they_applied() -> None:
    rig = Rig()
    out = rig.call("walk", op="start", x=0.1, turn=0.2)
    assert out["amplitude"]["x_mm"] == pytest.approx(15.0) and out["walking"]
    with pytest.raises(Reject) as err:
        rig.call("walk", op="start", x=1.0)
    assert err.value.field == "x" and err.value.code == "out_of_range"
    assert rig.call("walk", op="stop")["stopping"] is True
    params = rig.call("walk_params", set={"period_time": 650.0})
    assert params["changed"] == {"period_time": 650.0} and params["params"]["period_time"] == 650
    with pytest.raises(Reject) as err:
        rig.call("walk_params", set={"dsp_ratio": 2})
    assert err.value.field == "set.dsp_ratio"
    assert rig.call("head", pan=0.5, tilt=0.1) == {"mode": "move", "pan": 0.5, "tilt": 0.1}
    assert rig.call("head", op="home")["tilt"] == pytest.approx(math.radians(10))
    with pytest.raises(Reject) as err:
        rig.call("head", pan=0.0, tilt=1.0)
    assert err.value.field == "tilt"
    played = rig.call("action", behaviour=301)
    assert played["page"] == 4 and played["sound"]["say"] == "Thank you"
    with pytest.raises(Reject) as err:
        rig.call("action", name="moonwalk")
    assert err.value.code == "unknown" and err.value.field == "name"
    table = rig.call("behaviours")
    assert {b["id"] for b in table["behaviours"]} >= {1, 4, 15, 16, 100, 301, 309}
    assert rig.call("sound", say="oi", lang="pt")["played"] == "event"
