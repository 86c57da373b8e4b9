"""The motion-authority rule (robot_daemon/motion_authority.py, issue 35 finding 2): a get-up
page plays only inside a lease holder's walk, ball play, behaviour or policy, never at start-up,
after a halt or with nobody's motion running; and the list of what the robot does by itself
names code that refers back to it."""

from __future__ import annotations

import re
from pathlib import Path

from robot_daemon.motion_authority import MOVES_BY_ITSELF
from tests.unit.test_motion_modules import Rig

REPO = Path(__file__).resolve().parents[2]


def _falls(rig: Rig) -> list[tuple[str, dict]]:
    return [(msg, d) for k, msg, d in rig.manager.drain_events() if k == "fall"]


def _lie_face_down(rig: Rig) -> None:
    rig.accel_y = 384
    rig.run(40)


def test_a_robot_lying_at_start_with_no_client_lies_still_and_says_why() -> None:
    rig = Rig()  # started, gyro centred, nobody holds the lease
    _lie_face_down(rig)
    falls = _falls(rig)
    assert [d for _, d in falls] == [
        {"state": "fallen_forward", "direction": "forward", "recovering": False, "page": None}
    ]
    assert "not getting up: nobody holds the lease" in falls[0][0]
    assert "play page 10" in falls[0][0]
    assert not rig.m("action").playing
    rig.run(200)
    assert not rig.m("action").playing and not _falls(rig)


def test_a_fall_inside_the_holders_walk_gets_up_and_after_a_halt_does_not() -> None:
    rig = Rig()
    rig.manager.controller = "c1"
    rig.m("walking").start(0.05, 0, 0)
    rig.run(200)
    _lie_face_down(rig)
    assert [d["recovering"] for _, d in _falls(rig)] == [True]
    assert rig.m("action").status()["page"] == 10
    # Again: walking, halted, then laid face down (the holder still holds the lease).
    rig = Rig()
    rig.manager.controller = "c1"
    rig.m("walking").start(0.05, 0, 0)
    rig.run(200)
    rig.manager.halt(finish_step=True)
    rig.run(100)
    _lie_face_down(rig)
    falls = _falls(rig)
    assert [d["recovering"] for _, d in falls] == [False]
    assert "no walk, ball play, behaviour or policy loop of the lease holder" in falls[0][0]
    assert not rig.m("action").playing


def test_a_fall_with_the_lease_held_but_no_motion_running_plays_nothing() -> None:
    rig = Rig()
    rig.manager.controller = "c1"
    _lie_face_down(rig)
    assert [d["recovering"] for _, d in _falls(rig)] == [False]
    assert not rig.m("action").playing


def test_the_lease_ending_during_a_walk_ends_the_right_to_get_up() -> None:
    rig = Rig()
    rig.manager.controller = "c1"
    rig.m("walking").start(0.05, 0, 0)
    rig.run(200)
    rig.manager.controller = None  # the daemon: the lease ended (and stop_all)
    rig.manager.stop_all()
    _lie_face_down(rig)
    falls = _falls(rig)
    assert [d["recovering"] for _, d in falls] == [False]
    assert "nobody holds the lease" in falls[0][0]
    assert not rig.m("action").playing and not rig.m("walking").running


def test_recovery_is_the_holders_motion_only_within_client_motion_s() -> None:
    """The policy loop stops itself when the body tilts, a moment before the robot lies: a
    fall within ``client_motion_s`` of the holder's motion is still inside it."""
    rig = Rig()
    rig.manager.controller = "c1"
    rig.m("walking").start(0.0, 0, 0)
    rig.run(20)
    rig.m("walking").halt()  # stopped by itself (as the policy's tilt check does)
    rig.manager.release("walking")
    rig.run(10)
    _lie_face_down(rig)
    assert [d["recovering"] for _, d in _falls(rig)] == [True]


def test_every_move_by_itself_names_code_that_refers_back_to_it() -> None:
    import robot_daemon.motion_authority as authority

    constants = {v: k for k, v in vars(authority).items() if k.startswith("MOVE_")}
    assert set(constants) == {m.name for m in MOVES_BY_ITSELF}, "a MOVE_ constant per entry"
    for move in MOVES_BY_ITSELF:
        source = (REPO / move.where).read_text()
        assert re.search(rf"\b{constants[move.name]}\b", source), (
            f"{move.where} does not refer to {constants[move.name]} ({move.what})"
        )

