"""The `trajectory` verb: checked whole before anything moves, then played in the loop."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from robot_daemon.arbiter.registry import Reject
from robot_daemon.motion.trajectory import Trajectory
from tests.unit.arbiter_rig import ArbiterRig
from tests.unit.motion_rig import DT, PerfectServos

PAN, TILT = 19, 20


def _points(*pts: tuple[float, list[float]]) -> list[dict[str, Any]]:
    return [{"t": t, "positions": p} for t, p in pts]


@pytest.fixture
def rig() -> ArbiterRig:
    return ArbiterRig()


def test_sample_is_linear_from_the_start_through_every_point() -> None:
    traj = Trajectory((PAN,), np.array([1.0, 2.0]), np.array([[0.4], [0.0]]))
    start = np.array([0.2])
    assert traj.sample(0.0, start)[0] == pytest.approx(0.2)
    assert traj.sample(0.5, start)[0] == pytest.approx(0.3)
    assert traj.sample(1.5, start)[0] == pytest.approx(0.2)
    assert traj.sample(9.0, start)[0] == pytest.approx(0.0)


@pytest.mark.parametrize(
    ("fields", "field", "code"),
    [
        ({"joints": ["head_pan"], "points": _points((1.0, [3.0]))}, "points[0].positions[0]",
         "out_of_range"),
        ({"joints": ["head_pan"], "points": _points((1.0, [math.nan]))},
         "points[0].positions[0]", "invalid"),
        ({"joints": ["nose"], "points": _points((1.0, [0.0]))}, "joints[0]", "unknown"),
        ({"joints": ["head_pan"], "points": _points((1.0, [0.0]), (0.5, [0.1]))},
         "points[1].t", "invalid"),
        ({"joints": ["head_pan"], "points": _points((1.0, [0.0, 0.1]))},
         "points[0].positions", "invalid"),
        ({"joints": ["head_pan"], "points": []}, "points", "invalid"),
        ({"joints": ["head_pan", 19], "points": _points((1.0, [0.0, 0.0]))}, "joints",
         "invalid"),
        ({"joints": ["head_pan"], "points": [{"t": 1.0, "positions": [0.0], "v": [1]}]},
         "points[0].v", "invalid"),
        ({"joints": ["head_pan"], "points": _points((1.0, [0.0]), (1.01, [1.0]))},  # 100 rad/s
         "points[1].positions[0]", "out_of_range"),
        ({"joints": ["head_pan"], "points": _points((700.0, [0.0]))}, "points[0].t",
         "out_of_range"),
    ],
)
def test_a_bad_trajectory_is_refused_whole_naming_the_point(
    rig: ArbiterRig, fields: dict[str, Any], field: str, code: str
) -> None:
    token = rig.acquire()
    with pytest.raises(Reject) as info:
        rig.send("trajectory", lease_token=token, **fields)
    assert (info.value.field, info.value.code) == (field, code), info.value.message
    assert not rig.manager.module("direct").active


def test_playing_needs_the_lease_and_stopping_does_not(rig: ArbiterRig) -> None:
    with pytest.raises(Reject) as info:
        rig.send("trajectory", joints=["head_pan"], points=_points((1.0, [0.1])))
    assert info.value.code == "no_lease"
    assert rig.send("trajectory", op="stop") == {"stopped": False}


def test_the_loop_plays_it_tick_by_tick_and_holds_the_last_point(rig: ArbiterRig) -> None:
    servos = PerfectServos(rig.manager)
    servos.step()
    token = rig.acquire()
    reply = rig.send("trajectory", lease_token=token, joints=["head_pan", "head_tilt"],
                     points=_points((0.4, [0.4, -0.2]), (0.8, [0.0, 0.0])))
    assert reply == {"joints": ["head_pan", "head_tilt"], "points": 2,
                                "duration": 0.8}
    seen = []
    for _ in range(round(1.0 / DT)):
        frame = servos.frame()
        servos.step(frame)
        seen.append((frame.time, servos.pos[PAN]))
    t0 = seen[0][0]
    for t, pan in seen:
        s = t - t0
        want = 0.4 * s / 0.4 if s <= 0.4 else max(0.0, 0.4 - 0.4 * (s - 0.4) / 0.4)
        assert pan == pytest.approx(want, abs=1e-9), s
    peak = max(pan for _, pan in seen)
    assert peak == pytest.approx(0.4)
    assert servos.pos[PAN] == pytest.approx(0.0) and servos.pos[TILT] == pytest.approx(0.0)
    assert rig.manager.module("direct").status().get("trajectory") is None


def test_stop_holds_where_it_is_and_a_new_pose_ends_it(rig: ArbiterRig) -> None:
    servos = PerfectServos(rig.manager)
    servos.step()
    token = rig.acquire()
    rig.send("trajectory", lease_token=token, joints=["head_pan"],
             points=_points((1.0, [0.5])))
    for _ in range(25):
        servos.step()
    assert rig.manager.module("direct").status()["trajectory"]["points"] == 1
    assert rig.send("trajectory", op="stop") == {"stopped": True}
    held = servos.pos[PAN]
    for _ in range(25):
        servos.step()
    assert 0.05 < held < 0.5 and servos.pos[PAN] == pytest.approx(held)

    rig.send("trajectory", lease_token=token, joints=["head_pan"],
             points=_points((1.0, [0.0])))
    servos.step()
    rig.send("joint", lease_token=token, name="head_pan", position=0.3)
    for _ in range(round(1.5 / DT)):
        servos.step()
    assert servos.pos[PAN] == pytest.approx(0.3)  # the joint verb won; the trajectory ended
