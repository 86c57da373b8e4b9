"""The action player: key frames on time, bounded speeds, via-points, pauses, chaining, stop,
brake, ownership."""

from __future__ import annotations

import math

import numpy as np
import pytest

from config.loader import load_robot
from robot_daemon.motion.action.binfile import Page, Step
from robot_daemon.motion.action.library import MotionLibrary, load_library
from robot_daemon.motion.action.player import ActionModule
from robot_daemon.motion.direct import DirectModule
from robot_daemon.motion.manager import MotionManager
from schemas.units import deg_to_raw
from tests.unit.motion_rig import DT, PerfectServos


class Rig(PerfectServos):
    def __init__(self, pages: list[Page]) -> None:
        super().__init__(MotionManager(load_robot()))
        self.action = ActionModule(MotionLibrary(pages))
        self.direct = DirectModule()
        self.manager.add(self.action)
        self.manager.add(self.direct)
        self.trace: list[np.ndarray] = []

    def run(self, ticks: int) -> None:
        for _ in range(ticks):
            self.step()
            self.trace.append(self.pos.copy())

    def run_until_idle(self, limit: int = 5000) -> int:
        start = self.tick
        while self.action.playing and self.tick - start < limit:
            self.run(1)
        return self.tick - start


def step(time: int, pause: int = 0, **deg: float) -> Step:
    s = Step(time=time, pause=pause)
    ids = {j.name: j.id for j in load_robot().joints}
    for name, d in deg.items():
        s.words[ids[name]] = deg_to_raw(d)
    return s


def test_each_key_frame_is_reached_at_its_time_and_speeds_are_bounded() -> None:
    page = Page(
        5,
        name="knee",
        steps=[
            step(50, r_knee=40, head_pan=10),
            step(25, r_knee=10, head_pan=10),
            step(100, pause=25, r_knee=60, head_pan=-20),
        ],
    )
    rig = Rig([page])
    rig.action.play(5)
    rig.run(50)
    assert math.degrees(rig.pos[13]) == pytest.approx(40, abs=0.05)
    assert math.degrees(rig.pos[19]) == pytest.approx(10, abs=0.05)
    rig.run(25)
    assert math.degrees(rig.pos[13]) == pytest.approx(10, abs=0.05)
    rig.run(100)
    assert math.degrees(rig.pos[13]) == pytest.approx(60, abs=0.05)
    assert math.degrees(rig.pos[19]) == pytest.approx(-20, abs=0.05)
    rig.run(24)
    assert rig.action.playing  # the pause holds the page
    assert rig.run_until_idle() <= 2
    trace = np.array(rig.trace)
    speed = np.abs(np.diff(trace[:, 13])) / DT
    # Within a step a joint never moves faster than twice the step's mean speed.
    bounds = [(0, 50, 40), (50, 75, 30), (75, 175, 50)]
    for a, b, dist in bounds:
        assert speed[a : b - 1].max() <= 2 * math.radians(dist) / ((b - a) * DT) + 1e-6
    # The trapezoid starts and ends at rest: first and last moves are small.
    assert speed[0] < 0.2 * speed[:50].max()


def test_a_joint_keeping_its_direction_passes_a_via_point_without_stopping() -> None:
    rig = Rig([Page(6, name="via", steps=[step(50, r_knee=30), step(50, r_knee=60)])])
    rig.action.play(6)
    rig.run(100)
    trace = np.degrees(np.array(rig.trace)[:, 13])
    assert trace[49] == pytest.approx(30, abs=0.05) and trace[99] == pytest.approx(60, abs=0.05)
    v_at_via = (trace[50] - trace[48]) / (2 * DT)
    assert v_at_via > 0.5 * 30 / (50 * DT)  # still moving through the key frame
    # A joint that reverses stops at the key frame instead.
    rig = Rig([Page(6, name="back", steps=[step(50, r_knee=30), step(50, r_knee=0)])])
    rig.action.play(6)
    rig.run(100)
    trace = np.degrees(np.array(rig.trace)[:, 13])
    assert abs(trace[50] - trace[48]) / (2 * DT) < 0.1 * 30 / (50 * DT)


def test_repeat_next_chaining_stop_plays_the_exit_page() -> None:
    a = Page(
        20, name="a", repeat=2, next=21, exit=22, steps=[step(10, r_knee=20), step(10, r_knee=0)]
    )
    b = Page(21, name="b", steps=[step(10, r_knee=50)])
    c = Page(22, name="c", steps=[step(10, r_knee=70)])
    rig = Rig([a, b, c])
    rig.action.play("a")
    ticks = rig.run_until_idle()
    assert ticks == 2 * 20 + 10
    assert math.degrees(rig.pos[13]) == pytest.approx(50, abs=0.05)
    events = [(d["page"], d["state"]) for k, _, d in rig.manager.drain_events() if k == "action"]
    assert events == [(20, "started"), (20, "finished"), (21, "started"), (21, "finished")]
    rig.action.play(20)
    rig.run(5)
    rig.action.stop()  # finish the current repetition, then the exit page instead of next
    ticks = rig.run_until_idle()
    assert math.degrees(rig.pos[13]) == pytest.approx(70, abs=0.05)
    assert 5 + ticks == 20 + 10


def test_brake_ends_the_current_step_at_rest_and_releases() -> None:
    rig = Rig([Page(8, name="long", steps=[step(50, r_knee=40), step(50, r_knee=80)])])
    rig.action.play(8)
    rig.run(20)
    rig.action.brake()
    ticks = rig.run_until_idle()
    assert ticks <= 31
    assert math.degrees(rig.pos[13]) == pytest.approx(40, abs=0.05)
    assert rig.manager.owner(13) is None


def test_another_module_taking_the_joints_interrupts_the_page() -> None:
    rig = Rig([Page(8, name="long", steps=[step(100, r_knee=40)])])
    rig.action.play(8)
    rig.run(10)
    rig.direct.set_joint(13, 0.3)
    rig.run(1)
    assert not rig.action.playing
    assert rig.manager.owner(13) == "direct"


def test_pages_leaving_the_joint_limits_are_refused() -> None:
    rig = Rig([Page(9, name="bad", steps=[step(10, r_knee=-30)])])
    with pytest.raises(ValueError, match=r"r_knee -30\.0° is outside"):
        rig.action.play(9)
    assert not rig.action.playing and rig.manager.owner(13) is None
    with pytest.raises(KeyError, match="no action page named 'nope'"):
        rig.action.play("nope")


def test_sit_down_then_stand_up_from_the_project_library_reach_their_poses() -> None:
    lib = load_library()
    rig = Rig(list(lib.pages.values()))
    for name in ("sit down", "stand up"):
        rig.action.play(name)
        rig.run_until_idle()
        last = lib.page(name).steps[-1]
        for j in range(1, 21):
            if last.driven(j):
                assert rig.pos[j] == pytest.approx((last.words[j] - 2048) * 2 * math.pi / 4096)


def test_play_from_a_step_goes_there_from_where_the_joints_are() -> None:
    page = Page(
        7,
        name="three",
        steps=[step(40, r_elbow=30.0), step(40, r_elbow=-30.0), step(40, r_elbow=10.0)],
    )
    rig = Rig([page])
    rig.action.play(7, step=3)
    rig.run_until_idle()
    elbow = [t[5] for t in rig.trace]
    assert rig.pos[5] == pytest.approx(math.radians(10.0), abs=1e-3)
    # Straight from 0° to 10°: never through the earlier steps' 30° and −30°.
    assert min(elbow) >= -1e-9 and max(elbow) <= math.radians(10.0) + 1e-3
    assert rig.tick < 60  # one step of 40 units, not three
    with pytest.raises(KeyError, match=r"steps 1\.\.3"):
        rig.action.play(7, step=4)


def test_page_slopes_set_the_p_gain_while_the_page_plays_as_action_cpp_does() -> None:
    # Action.cpp (MX-28 build): P = (256 >> (slope >> 4)) << 2 — 0x55 → 32 (the default, not
    # written), 0x44 → 64, 0x33 → 128, 0x77 → 8; back to the configured gains when it ends.
    slopes = bytearray(bytes.fromhex("55" * 26 + "00" * 5))
    slopes[10], slopes[15], slopes[3] = 0x33, 0x44, 0x77
    page = Page(
        number=5,
        name="stiff",
        steps=[step(20, r_shoulder_roll=-20, l_hip_roll=5, r_ankle_pitch=5, r_knee=10)],
        slopes=bytes(slopes),
    )
    rig = Rig([page])
    rig.action.play(5)
    rig.run(2)

    def gains() -> dict[int, tuple[int, int, int]]:
        return rig.step().gains

    assert gains() == {3: (8, 0, 0), 10: (128, 0, 0), 15: (64, 0, 0)}
    rig.run_until_idle()
    assert gains() == {}


def test_the_kick_pages_stiffen_the_standing_legs_roll_joints() -> None:
    lib = load_library()
    for number, stance in ((12, (10, 18)), (13, (9, 17))):
        page = lib.page(number)
        assert [page.slopes[j] for j in stance] == [0x33, 0x33]  # P 128
        assert page.slopes[15] == page.slopes[16] == 0x44  # the stock file's ankle pitch
