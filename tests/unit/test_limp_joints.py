"""No motion on a limp leg (issue 35, finding 4), on the emulator through the daemon's own bus
code (SimRig: the in-process link, the kinematic world) and the real verb handlers: a walk,
a page, ball play, a choreography and the policy loop are refused while a joint they drive is
offline, refused (old firmware) or torque off, in one line naming the servo; a driven joint
that overheats or stops answering mid-walk stops the walk at its next double support; the goals
of a torqued joint whose replies are lost keep being written, so it does not jump on return."""

from __future__ import annotations

import copy
import math
from typing import Any

import pytest

from config.loader import load_all
from robot_daemon.arbiter.core import execute, parse_request
from robot_daemon.arbiter.lease import Lease
from robot_daemon.arbiter.registry import MotionContext
from robot_daemon.arbiter.verbs import load_all as load_verbs
from robot_daemon.bus.tables import MX28
from schemas.errors import CommandError
from schemas.messages import command_payload
from tests.fixtures.sim_rig import SimRig

R_KNEE = 13


class Rig(SimRig):
    """A simulated robot with a lease holder sending verbs through the real pipeline."""

    def __init__(self, **emulator: Any) -> None:
        load_verbs()
        settings = copy.deepcopy(load_all())
        settings.setdefault("emulator", {}).update(emulator)
        super().__init__(seed=3, settings=settings, vision_fps=0.5)
        self.lease = Lease(600.0, heartbeat_timeout=0.0)
        self.token = self.lease.acquire("c1", "tester").token
        self.manager.controller = "c1"
        assert self.calibrated()

    def send(self, verb: str, **fields: Any) -> dict[str, Any]:
        ctx = MotionContext(
            robot=self.robot,
            manager=self.manager,
            bus=self.bus,
            settings=self.settings,
            frame=self.bus.frame(self.tick, self.time, self.tick_s),
            emit=self._emit,
            lease=self.lease,
        )
        payload = command_payload("c1", lease_token=self.token, **fields)
        return execute(parse_request(verb, payload), ctx, self.lease)

    def stopped_events(self) -> list[tuple[str, dict[str, Any]]]:
        return [(m, d) for k, m, d in self.manager.drain_events() if k == "motion_stopped"]


def _refusal(rig: Rig, verb: str, **fields: Any) -> str:
    with pytest.raises(CommandError) as err:
        rig.send(verb, **fields)
    assert err.value.code == "unavailable"
    return err.value.message


def test_motion_is_refused_naming_the_servo_kept_offline_for_old_firmware() -> None:
    rig = Rig(old_firmware_ids=[7])
    assert 7 in rig.bus.refused
    message = _refusal(rig, "walk", op="start", x=0.05)
    assert message.startswith("walk refused: servo 7 (r_hip_yaw) has MX-28 firmware")
    assert "\n" not in message and "upgrade it" in message
    assert "servo 7" in _refusal(rig, "action", page=1)
    assert "servo 7" in _refusal(rig, "policy", op="start")
    assert "servo 7" in _refusal(rig, "choreography", items=[{"behaviour": 100}])
    rig.run(0.5)
    assert not rig.manager.module("walking").running
    assert not rig.manager.module("action").playing
    # What does not drive servo 7 still moves.
    assert rig.send("head", pan=0.3)["mode"] == "move"


def test_a_torque_off_leg_refuses_a_walk_and_a_page() -> None:
    rig = Rig()
    rig.send("torque", enable=False, ids=[R_KNEE])
    rig.step()
    message = _refusal(rig, "walk", op="start")
    assert message == (
        "walk refused: servo 13 (r_knee) has torque off: enable it first (`torque` enable=true)"
    )
    assert "servo 13" in _refusal(rig, "action", page=9)


def _walking(rig: Rig) -> Any:
    walking = rig.manager.module("walking")
    rig.send("walk", op="start", x=0.05)
    rig.run_until(lambda _r: walking.running and not walking.sequencing and not walking._ready_t,
                  timeout=5.0)
    rig.run(1.0)
    assert walking.running
    rig.manager.drain_events()
    return walking


def test_an_overheating_knee_mid_walk_stops_the_walk_at_double_support() -> None:
    rig = Rig()
    walking = _walking(rig)
    rig.emulator.api.overheat(R_KNEE)
    period = walking.period / 1000
    # The alarm is read in the slow round-robin (one servo a tick): within 20 ticks, then the
    # walk ends within half a period.
    assert rig.run_until(lambda _r: not walking.running, timeout=20 * rig.tick_s + period)
    events = rig.stopped_events()
    assert len(events) == 1
    message, data = events[0]
    assert data["ids"] == [R_KNEE] and "walking" in data["modules"]
    assert "servo 13 (r_knee) torque off" in message
    assert "the walk ends at its next double support" in message
    rig.run(1.0)
    assert not walking.running and rig.stopped_events() == []  # one event, no restart


def test_a_knee_whose_replies_are_lost_stops_the_walk_keeps_its_goals_and_does_not_jump() -> None:
    rig = Rig()
    walking = _walking(rig)
    rig.emulator.api.silence(R_KNEE)  # it still hears and obeys; it no longer answers
    assert rig.run_until(lambda _r: not rig.bus.state.online[R_KNEE], timeout=1.0)
    assert rig.run_until(lambda _r: not walking.running, timeout=walking.period / 1000)
    assert [d["ids"] for _, d in rig.stopped_events()] == [[R_KNEE]]
    rig.run(1.0)
    held = rig.manager._last_goal[R_KNEE]
    servo_goal = rig.bus.joint_to_raw(R_KNEE, held)
    assert rig.emulator.bus.servos[R_KNEE].table[MX28.GOAL_POSITION] == servo_goal  # it heard
    rig.emulator.api.silence(R_KNEE, False)
    assert rig.run_until(lambda _r: bool(rig.bus.state.online[R_KNEE]), timeout=2.0)
    rig.run(0.2)
    back = rig.frame().position[R_KNEE]
    assert math.degrees(abs(back - held)) < 2.0  # where it was held: no jump on return


# -- issue 35, finding 8: where a motion starts, and the walk's arms ------------------------------
@pytest.mark.parametrize("verb", ["pose", "action", "walk"])
def test_a_motion_starts_from_the_goal_a_sagging_joint_holds_not_where_it_sags_to(
    verb: str,
) -> None:
    """A loaded P-only servo stands below its goal. A pose, a page and the walk (its walk-ready
    page) used to start from the present position: their first goal dropped the knee by the sag
    at once. They start from the goal it holds, as ROBOTIS's Action.cpp does."""
    rig = Rig(sag_units=80.0)
    rig.emulator.api.set_external_load(R_KNEE, 0.8)
    rig.run(1.0)
    st = rig.bus.state
    held, present = int(st.goal[R_KNEE]), int(st.position[R_KNEE])
    assert abs(held - present) >= 30, "the knee does not sag: nothing to tell apart"
    if verb == "pose":
        target = rig.bus.raw_to_joint(R_KNEE, held) + 0.3
        rig.send("pose", positions={"r_knee": target}, duration=1.0)
    elif verb == "action":
        rig.send("action", page=1)
    else:
        rig.send("walk", op="start")
    firsts: list[int] = []
    while len(firsts) < 3:
        rig.step()
        if int(st.goal[R_KNEE]) != held or firsts:
            firsts.append(int(st.goal[R_KNEE]))
    # The first goals move on from the held goal by a little, never to the sagged position.
    assert abs(firsts[0] - held) <= 5, (held, present, firsts)


def test_the_walk_owns_all_six_arm_servos_soft_at_the_walks_arm_pose() -> None:
    rig = Rig()
    walking = _walking(rig)
    assert walking.running
    for j in (1, 2, 3, 4, 5, 6):
        assert rig.manager.owner(j) == "walking"
        assert rig.emulator.bus.servos[j].table[MX28.P_GAIN] == 8  # Walking.cpp: SetPGain 8
    for j, deg in ((3, -17.873), (4, 17.580), (5, 29.300), (6, -29.593)):
        assert math.degrees(rig.manager._last_goal[j]) == pytest.approx(deg, abs=0.01)
    rig.send("walk", op="stop")
    assert rig.run_until(lambda _r: not walking.active, timeout=3.0)
    rig.step()
    assert rig.emulator.bus.servos[5].table[MX28.P_GAIN] == 32  # its configured gain again
