"""Teach mode through the Robot client against ``darwin up`` (emulator, daemon): limp the right
arm, move it by hand through the emulator's control API, capture, mirror, save, reload, play,
and the emulator's goals reach the captured angles. Pages go to a temporary user library."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import pytest

from clients.pages import joints_of
from schemas.errors import ClientError, InvalidCommandError, NoLeaseError
from schemas.sim_control import SimControl
from tests.fixtures.system import EventLog, RunningSystem, start_system

# Right arm moved "by hand": ids 1, 3, 5 (rad, inside the configured limits).
BY_HAND = {1: -1.0, 3: 0.3, 5: 0.8}


@pytest.fixture(scope="module")
def teach_system(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[RunningSystem, Path]]:
    user = tmp_path_factory.mktemp("motions")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("DARWIN_MOTIONS", str(user))
        with start_system(gateway=False) as system:
            yield system, user


def sim_servos(sim: SimControl) -> dict[int, dict]:
    return {int(k): v for k, v in sim.call("state")["servos"].items()}


def test_limp_move_capture_mirror_save_reload_play(teach_system) -> None:
    system, user = teach_system
    events = EventLog()
    with system.robot_client(name="teacher") as robot:
        sim = SimControl(robot.session, system.robot)
        robot.subscribe("events", events)
        robot.wait_for("joints")
        with pytest.raises(NoLeaseError):
            robot.page_put({"number": 200, "name": "x", "step": [{"time": 5}]})
        with robot.control("teacher"):
            page = robot.page_editor(200, "taught")
            assert page.page["step"] == []
            # Legs hold the robot up: they go limp only when confirmed.
            with pytest.raises(ClientError, match="confirm=True"):
                robot.limp("legs")
            assert robot.limp("right_arm") == joints_of("right_arm")
            robot.wait_for(
                "joints", lambda m: not any(m.torque_enabled[i - 1] for i in BY_HAND), timeout=10
            )
            for jid, rad in BY_HAND.items():
                sim.call("set_position", id=jid, rad=rad)
            robot.wait_for(
                "joints",
                lambda m: all(abs(m.position[j - 1] - r) < 0.005 for j, r in BY_HAND.items()),
                timeout=10,
            )
            page.insert_step(0, {})
            stored = robot.capture(page, 0)
            assert set(stored) == set(joints_of("right_arm"))
            for jid, rad in BY_HAND.items():
                assert stored[robot.state.joints.name[jid - 1]] == pytest.approx(
                    math.degrees(rad), abs=0.1
                )
            robot.wait_for(
                "joints", lambda m: all(m.torque_enabled[i - 1] for i in BY_HAND), timeout=10
            )
            # Mirror (right onto left), undo, mirror again: the left arm gets the negated angles.
            page.mirror(0, "right")
            page.undo()
            assert "l_elbow" not in page.step(0)
            page.mirror(0, "right")
            step = page.step(0)
            for name in ("shoulder_pitch", "shoulder_roll", "elbow"):
                assert step[f"l_{name}"] == -step[f"r_{name}"]
            page.step(0)["time"] = 60
            saved = robot.page_put(page)
            assert Path(saved["path"]).parent == user
            assert robot.pages_reload()["pages"] >= 20
            assert robot.page(200)["step"][0] == step

            # Move the arms away, then play the page: the goals come back to the captured pose.
            zero = {j: 0.0 for j in joints_of("arms")}
            robot.pose(zero, duration=0.3)
            robot.wait_for(
                "joints", lambda m: all(abs(m.position[i]) < 0.02 for i in range(6)), timeout=10
            )
            robot.page_play(200)
            finished = events.wait(
                lambda e: e.kind == "action" and e.message == "page 200 (taught) finished",
                timeout=15,
            )
            # The event goes out after that tick's goals are written, but the emulator may not
            # have read them off the pty yet (a loaded host): a later tick's reading was answered
            # after them (one ordered stream), so then its registers hold them.
            robot.wait_for("joints", lambda m: m.stamp > finished.stamp, timeout=10)
            servos = sim_servos(sim)
            for name, deg in step.items():
                if name in ("time", "pause"):
                    continue
                jid = robot.state.joints.name.index(name) + 1
                assert servos[jid]["goal"] == pytest.approx(math.radians(deg), abs=0.003), name

            # Invalid pages are refused naming the field; the player's page stays.
            bad = dict(page.page, name="far too long a name")
            with pytest.raises(InvalidCommandError) as err:
                robot.page_put(bad)
            assert err.value.field == "page.name"
            data = robot.pages_export()
            assert len(data) == 131072
            assert robot.page_delete(200)["number"] == 200
            assert not list(user.glob("*.toml"))

            # A block of teach mode: the head limp inside it, torque back on after.
            with robot.teaching("head") as limp:
                assert limp == ["head_pan", "head_tilt"]
                robot.wait_for("joints", lambda m: not any(m.torque_enabled[18:20]), timeout=10)
            robot.wait_for("joints", lambda m: all(m.torque_enabled[18:20]), timeout=10)
