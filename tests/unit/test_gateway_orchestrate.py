"""Orchestrate lists → choreography items, against the table the daemon's `behaviours` verb
answers (the library shipped in config/behaviours.toml)."""

from __future__ import annotations

import pytest

from config.loader import load_section
from gateway.messages import MessageError, Orchestrate, PlayItem, TimeItem
from gateway.orchestrate import BehaviourTable, choreography_items
from robot_daemon.motion.behaviours import BehaviourLibrary
from schemas.errors import ErrorCode


@pytest.fixture(scope="module")
def table() -> BehaviourTable:
    return BehaviourTable(BehaviourLibrary(load_section("behaviours")).listing())


def kind_of(table: BehaviourTable, kind: str) -> int:
    return next(t for t, k in table.types.items() if k == kind)


def test_appendix_example(table: BehaviourTable) -> None:
    req = Orchestrate((PlayItem(9, 5), PlayItem(325, 1), TimeItem(20.0)))
    items = choreography_items(req, table)
    assert items[0] == {"behaviour": 9}  # type 5: any behaviour by id
    assert items[1] == {"page": 325}  # type 1: an action page (the daemon says it is missing)
    forward = table.forward_walk()
    assert forward is not None and items[2] == {"behaviour": forward["id"], "duration": 20.0}


def test_time_sets_the_latest_walk(table: BehaviourTable) -> None:
    walk = kind_of(table, "walk")
    walk_id = next(i for i, b in table.behaviours.items() if b["kind"] == "walk")
    action_id = next(i for i, b in table.behaviours.items() if b["kind"] == "action")
    req = Orchestrate(
        (PlayItem(walk_id, walk), PlayItem(action_id, 1), TimeItem(4.0), TimeItem(2.0))
    )
    items = choreography_items(req, table)
    assert items[0] == {"behaviour": walk_id, "duration": 4.0}
    assert items[1] == {"behaviour": action_id}
    assert items[2]["duration"] == 2.0  # no walk left without a time: walk forward


def test_unknown_type_and_wrong_kind_are_named(table: BehaviourTable) -> None:
    with pytest.raises(MessageError, match="type 99 is unknown; the robot's types are 1 = "):
        choreography_items(Orchestrate((PlayItem(1, 99),)), table)
    led_id = next(i for i, b in table.behaviours.items() if b["kind"] == "led")
    with pytest.raises(MessageError, match=f"item 0: behaviour {led_id} .* is a led, not a walk"):
        choreography_items(Orchestrate((PlayItem(led_id, kind_of(table, "walk")),)), table)
    with pytest.raises(MessageError, match="page 9999 is not a behaviour id") as e:
        choreography_items(Orchestrate((PlayItem(9999, kind_of(table, "walk")),)), table)
    assert e.value.code == ErrorCode.UNKNOWN
