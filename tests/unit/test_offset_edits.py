"""Joint-offset edits as the TUI makes them: a key pressed again before the daemon answered
goes a step further, answers arrive in order, refusals put the view and the history back."""

from __future__ import annotations

import pytest

from clients.calibration import OffsetEdits

ZERO = {"r_knee": 0.0, "l_knee": 0.0}


def test_nudges_sent_before_any_answer_add_up() -> None:
    edits = OffsetEdits(dict(ZERO))
    sent = [edits.nudge("r_knee", 0.5) for _ in range(3)]
    assert sent == [{"r_knee": 0.5}, {"r_knee": 1.0}, {"r_knee": 1.5}]
    assert edits.offsets["r_knee"] == 1.5 and edits.pending == 3
    # The first two answers are older than the view: it stays; the last replaces it.
    edits.applied({"r_knee": 0.5, "l_knee": 0.0})
    edits.applied({"r_knee": 1.0, "l_knee": 0.0})
    assert edits.offsets["r_knee"] == 1.5
    edits.applied({"r_knee": 1.5, "l_knee": 0.0})
    assert edits.pending == 0 and edits.offsets == {"r_knee": 1.5, "l_knee": 0.0}


def test_the_last_answer_is_the_daemons_word() -> None:
    edits = OffsetEdits(dict(ZERO))
    edits.nudge("r_knee", 0.5)
    edits.applied({"r_knee": 0.25, "l_knee": 0.0})  # e.g. the daemon rounded it
    assert edits.offsets["r_knee"] == 0.25


def test_a_get_answered_while_changes_are_in_flight_does_not_undo_them() -> None:
    edits = OffsetEdits(dict(ZERO))
    edits.nudge("r_knee", 0.5)
    edits.applied(dict(ZERO), answers_change=False)
    assert edits.offsets["r_knee"] == 0.5 and edits.pending == 1


def test_a_refused_change_puts_the_view_and_the_history_back() -> None:
    edits = OffsetEdits(dict(ZERO))
    edits.nudge("r_knee", 0.5)
    edits.applied({"r_knee": 0.5, "l_knee": 0.0})
    edits.mirror("r_knee")
    assert edits.offsets["l_knee"] == -0.5
    edits.refused()
    assert edits.offsets == {"r_knee": 0.5, "l_knee": 0.0} and len(edits.history) == 1
    assert edits.undo() == {"r_knee": 0.0}  # the undo is of the nudge, the mirror never was


def test_a_refused_undo_can_be_undone_again() -> None:
    edits = OffsetEdits(dict(ZERO))
    edits.nudge("r_knee", 0.5)
    edits.applied({"r_knee": 0.5, "l_knee": 0.0})
    assert edits.undo() == {"r_knee": 0.0} and edits.offsets["r_knee"] == 0.0
    edits.refused()
    assert edits.offsets["r_knee"] == 0.5 and edits.undo() == {"r_knee": 0.0}


def test_a_refusal_with_changes_still_in_flight_leaves_the_view_to_their_answers() -> None:
    edits = OffsetEdits(dict(ZERO))
    edits.nudge("r_knee", 0.5)
    edits.nudge("l_knee", 0.5)
    edits.refused()  # the first: the second's answer will say what the daemon holds
    assert edits.pending == 1 and len(edits.history) == 1
    edits.applied({"r_knee": 0.0, "l_knee": 0.5})
    assert edits.offsets == {"r_knee": 0.0, "l_knee": 0.5}


def test_nothing_to_undo_or_to_send() -> None:
    edits = OffsetEdits(dict(ZERO))
    with pytest.raises(ValueError, match="nothing to undo"):
        edits.undo()
    assert edits.reset(["r_knee"]) == {"r_knee": 0.0}  # sent though equal: the daemon's word
    edits.applied(dict(ZERO))
    edits.refused()  # an answer with nothing in flight: ignored
    assert edits.pending == 0 and edits.offsets == ZERO
