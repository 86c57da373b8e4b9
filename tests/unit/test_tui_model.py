"""The TUI's model: what arrived since a moment, even once the log has wrapped."""

from __future__ import annotations

from clients.tui.model import EVENTS, Model
from schemas.messages import Event


def _add(model: Model, *messages: str) -> None:
    for m in messages:
        model.add_event(Event(kind="info", message=m))


def test_events_since_a_count_are_the_newer_ones_in_order() -> None:
    model = Model()
    _add(model, "a", "b")
    before = model.event_count
    assert model.events_since(before) == []
    _add(model, "c", "d")
    assert [e.message for e in model.events_since(before)] == ["c", "d"]
    assert [e.message for e in model.events_since(0)] == ["a", "b", "c", "d"]


def test_events_since_survive_the_log_wrapping() -> None:
    model = Model()
    _add(model, *(f"old {i}" for i in range(EVENTS)))
    before = model.event_count
    _add(model, "new 1", "new 2")
    assert [e.message for e in model.events_since(before)] == ["new 1", "new 2"]
    # More arrived than the log holds: all that it still holds, no more.
    _add(model, *(f"newer {i}" for i in range(EVENTS + 5)))
    since = model.events_since(before)
    assert len(since) == EVENTS and since[-1].message == f"newer {EVENTS + 4}"
