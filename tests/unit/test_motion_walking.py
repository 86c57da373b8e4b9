"""The walking engine stepped with synthetic frames: alternating swings at the configured
period, feet inside the joint limits, latching, acceleration limits, stopping at a step's end."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from config.loader import load_all, load_robot
from robot_daemon.frames import JointFrame
from robot_daemon.motion.manager import MotionManager
from robot_daemon.motion.walking.gait import (
    WalkingModule,
    amplitudes_from_si,
    foot_heights,
    si_from_amplitudes,
)
from robot_daemon.motion.walking.params import WalkParams
from schemas.gait import GAIT_PARAM_UNITS, gait_label
from schemas.kinematics import leg_fk
from tests.unit.motion_rig import DT, PerfectServos


class Rig(PerfectServos):
    def __init__(self, **params: object) -> None:
        self.robot = load_robot()
        super().__init__(MotionManager(self.robot))
        p = WalkParams.from_config(load_all()["walking"])
        p.update(dict(params))
        self.walk = WalkingModule(p)
        self.manager.add(self.walk)
        self.goals: list[dict[int, float]] = []
        self.gyro = np.full(3, 512)

    def run(self, ticks: int) -> None:
        for _ in range(ticks):
            f = self.frame()
            f.gyro_raw = self.gyro.copy()
            self.goals.append(dict(self.step(f).goal))

    def run_while_walking(self, limit: int = 3000) -> int:
        n = 0
        while self.walk.running and n < limit:
            self.run(1)
            n += 1
        return n


def _ready_ticks(rig: Rig) -> int:
    return math.ceil(rig.walk.params.ready_time / DT) + 1


def test_si_to_amplitude_mapping_round_trips() -> None:
    x, y, a = amplitudes_from_si(0.1, 0.05, 0.5, 600)
    assert (x, y) == pytest.approx((15.0, 15.0)) and a == pytest.approx(math.degrees(0.15))
    assert si_from_amplitudes(x, y, a, 600) == pytest.approx((0.1, 0.05, 0.5))


def test_walking_alternates_swings_at_the_period_with_feet_inside_limits() -> None:
    rig = Rig()
    rig.walk.start(0.1, 0.0, 0.0)
    rig.run(_ready_ticks(rig))
    rig.goals.clear()
    period_ticks = round(rig.walk.params.period_time / 1000 / DT)
    rig.run(period_ticks * 4)
    lean = math.radians(rig.walk.params.hip_pitch_offset)
    heights = np.array([foot_heights(g, lean) for g in rig.goals])
    lifted_r, lifted_l = heights[:, 0] > 0.01, heights[:, 1] > 0.01
    assert not np.any(lifted_r & lifted_l)  # never both feet in the air
    starts = [i for i in range(1, len(heights)) if lifted_l[i] and not lifted_l[i - 1]]
    assert np.diff(starts).tolist() == [period_ticks] * (len(starts) - 1) and len(starts) >= 3
    r_starts = [i for i in range(1, len(heights)) if lifted_r[i] and not lifted_r[i - 1]]
    pairs = zip(starts, r_starts, strict=False)
    assert all(abs((r - left) - period_ticks / 2) <= 1 for left, r in pairs)
    assert heights.max() == pytest.approx(rig.walk.params.foot_height / 1000, abs=0.004)
    for g in rig.goals:
        for j, v in g.items():
            assert rig.robot.by_id[j].within(v), (j, math.degrees(v))
    # The swing foot moves forward: the left sole's x grows during its swing.
    i = starts[1]
    xs = [leg_fk(_pos(rig.goals[k]), "left")[0, 3] for k in range(i, i + 20)]
    assert xs[-1] > xs[0] + 0.01


def _pos(goals: dict[int, float]) -> np.ndarray:
    pos = np.zeros(21)
    for j, v in goals.items():
        pos[j] = v
    return pos


def test_commands_latch_at_mid_swing_within_acceleration_limits() -> None:
    rig = Rig()
    rig.walk.start(0.2, 0.0, 0.0)  # 30 mm: reached in steps of accel_x = 10 mm
    rig.run(_ready_ticks(rig))
    seen = []
    for _ in range(300):
        rig.run(1)
        if not seen or seen[-1] != rig.walk.latched[0]:
            seen.append(rig.walk.latched[0])
    assert seen[:4] == [0.0, 10.0, 20.0, 30.0]


def test_stop_ends_at_the_end_of_a_step_with_feet_together() -> None:
    rig = Rig()
    rig.walk.start(0.1, 0.0, 0.0)
    rig.run(_ready_ticks(rig) + 137)
    rig.walk.stop()
    ticks = rig.run_while_walking()
    step_ticks = rig.walk.params.period_time / 1000 / DT / 2
    assert ticks <= 1.5 * step_ticks + 1  # the current step, and one to bring the feet together
    assert not rig.walk.running
    last = _pos(rig.goals[-1])
    assert leg_fk(last, "left")[0, 3] == pytest.approx(leg_fk(last, "right")[0, 3], abs=1e-3)
    rig.run(1)
    assert rig.manager.owned_by("walking") == set()  # legs handed back, pose held
    events = [d["state"] for k, _, d in rig.manager.drain_events() if k == "walk"]
    assert events == ["started", "stopped"]


def test_unreachable_targets_are_skipped_never_sent() -> None:
    rig = Rig()
    rig.walk.start(0.0, 0.0, 0.0)
    rig.run(_ready_ticks(rig) + 10)
    assert rig.walk.skipped == 0 and rig.goals[-1]
    # z = 0 stretches the legs fully; with the feet set back they cannot reach: nothing sent.
    rig.walk.params.update({"z_offset": 0.0, "swing_top_down": 0.0, "x_offset": -50.0})
    rig.goals.clear()
    rig.run(20)
    assert rig.walk.skipped >= 20 and all(not g for g in rig.goals)
    # A stance out of reach from the start is refused before anything moves.
    rig = Rig(z_offset=0.0, swing_top_down=0.0, x_offset=-50.0)
    rig.walk.start(0.0, 0.0, 0.0)
    rig.run(5)
    assert not rig.walk.running and all(not g for g in rig.goals)
    assert "out of reach" in rig.manager.drain_events()[-1][1]


def test_gyro_feedback_moves_the_ankles() -> None:
    calm, shaken = Rig(), Rig()
    shaken.gyro = np.array([512, 560, 512])  # pitching forward
    for rig in (calm, shaken):
        rig.walk.start(0.0, 0.0, 0.0)
        rig.run(_ready_ticks(rig) + 5)
    assert calm.goals[-1][15] != pytest.approx(shaken.goals[-1][15], abs=1e-3)
    assert calm.goals[-1][11] == pytest.approx(shaken.goals[-1][11], abs=1e-9)


def test_parameters_are_checked_and_applied_atomically() -> None:
    p = WalkParams()
    with pytest.raises(ValueError, match="period_time=50"):
        p.update({"foot_height": 30.0, "period_time": 50})
    assert p.foot_height == 40.0
    with pytest.raises(ValueError, match="unknown walking parameter 'speed'"):
        p.update({"speed": 1})
    assert p.update({"period_time": 700, "balance_enable": False}) == {
        "period_time": 700.0,
        "balance_enable": False,
    }


def test_every_gait_parameter_has_a_unit_unless_it_is_a_ratio_or_gain() -> None:
    names = {f.name for f in dataclasses.fields(WalkParams)}
    unitless = {
        "dsp_ratio",
        "step_forward_back_ratio",
        "balance_enable",
        "balance_knee_gain",
        "balance_ankle_pitch_gain",
        "balance_hip_roll_gain",
        "balance_ankle_roll_gain",
        "p_gain",
        "i_gain",
        "d_gain",
    }
    assert set(GAIT_PARAM_UNITS) <= names, "a unit for a parameter that no longer exists"
    assert names - set(GAIT_PARAM_UNITS) == unitless
    assert gait_label("foot_height") == "foot_height (mm)"
    assert gait_label("dsp_ratio") == "dsp_ratio"


def test_late_ticks_cost_no_steps_and_skip_no_phase() -> None:
    """Gait time follows each frame's real dt: ticks arriving irregularly late (as under bus
    faults) take as many steps per second as steady ones, every step boundary still fires, and
    a stop still ends at a step's end."""
    seconds = 12.0
    counts = []
    for pattern in ([DT], [DT, 0.021, DT, 0.013, 0.032, DT, 0.017]):
        rig = Rig()
        rig.walk.start(x=0.05)
        t, k = 0.0, 0
        while t < seconds:
            dt = pattern[k % len(pattern)]
            f = JointFrame(k, t, dt, position=rig.pos.copy())
            f.gyro_raw = rig.gyro.copy()
            for j, g in rig.manager.step(f).goal.items():
                rig.pos[j] = g
            t += dt
            k += 1
        counts.append(rig.walk.steps)
        rig.walk.stop()
        rig.run_while_walking()
        assert not rig.walk.running  # the stop found its step boundary
    steady, late = counts
    assert abs(late - steady) <= 1, counts


def test_status_owners_follow_every_claim_and_release() -> None:
    # status's "owners" is made again only when ownership changed (it cost ~30 k instructions
    # a message): each claim and release shows, and a caller changing the dict it got does not
    # change the next one.
    rig = Rig()
    manager = rig.manager
    first = manager.status()["owners"]
    assert first == {str(j): manager.owner(j) for j in rig.robot.ids}
    legs = {j for j in rig.robot.ids if j > 6}
    manager.claim("walking", legs)
    owners = manager.status()["owners"]
    assert all(owners[str(j)] == "walking" for j in legs) and owners != first
    owners["7"] = "someone else"
    assert manager.status()["owners"]["7"] == "walking"
    manager.release("walking", {7})
    assert manager.status()["owners"]["7"] is None
    assert manager.status()["owners"] == {str(j): manager.owner(j) for j in rig.robot.ids}
