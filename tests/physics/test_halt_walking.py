"""`halt` while walking never drops the robot (issue 35, finding 3).

`halt` is every UI's emergency button. Frozen at once mid-step, the walk left the swing foot in
the air (up to the step height) with the body swayed over the stance foot, and the MuJoCo robot
tipped over. Now the walk ends at its next double support, within half a gait period, and holds
there. Each try walks forward on the MuJoCo plant (lock-step, the daemon's own motion and bus
code), sends the real `halt` verb at one of ``POINTS`` evenly spaced points of a gait period,
then watches for ``WATCH_S``: the robot never falls, the walk has ended within half a period,
and both feet of the pose it holds are down (the goals' sole heights, and the plant's soles).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest

from robot_daemon.arbiter.core import execute, parse_request
from robot_daemon.arbiter.lease import Lease
from robot_daemon.arbiter.registry import MotionContext
from robot_daemon.arbiter.verbs import load_all as load_verbs
from robot_daemon.motion.walking.gait import foot_heights
from schemas.messages import command_payload
from tests.fixtures.sim_rig import SimRig
from tests.physics import parallel

POINTS = 8  # halt points per gait period
WALK_S = 3.0  # walking before the halt: past the walk-ready page, at speed
WATCH_S = 2.5  # after it
FOOT_DOWN_M = 0.003  # a held sole this high above the other is "down" (goals)
PLANT_FOOT_M = 0.006  # the plant's soles: servo tracking and ground contact added


@dataclass
class Halted:
    phase_ms: float  # where in the period the halt came
    ended_ms: float  # how long the walk went on after it
    goal_feet_mm: float  # the higher sole of the held goals above the lower
    plant_feet_mm: float  # the same on the plant, WATCH_S after the halt
    falls: int
    period_ms: float


def _sole_heights(rig: SimRig) -> tuple[float, float]:
    data = rig.world.data  # type: ignore[attr-defined]
    return float(data.geom("r_foot").xpos[2]), float(data.geom("l_foot").xpos[2])


def halt_at(point: int) -> Halted:
    load_verbs()
    rig = SimRig(seed=5, physics="mujoco", vision_fps=0)
    walking = rig.manager.module("walking")
    walking.start(0.1, 0.0, 0.0)
    rig.run(WALK_S)
    assert walking.running and not walking.status()["stopping"], "not walking before the halt"
    period = walking.period
    target = point * period / POINTS
    # The next tick whose gait clock is at the point (the clock advances a tick at a time).
    half_tick = rig.tick_s * 500
    rig.run_until(lambda _r: abs(walking.time_ms - target) <= half_tick, timeout=period / 1000 * 2)
    phase = walking.time_ms
    ctx = MotionContext(
        robot=rig.robot,
        manager=rig.manager,
        bus=rig.bus,
        settings=rig.settings,
        frame=None,
        emit=rig._emit,
        lease=Lease(60.0, heartbeat_timeout=0.0),
    )
    execute(parse_request("halt", command_payload("ui", client_name="ui")), ctx, ctx.lease)
    t0 = rig.time
    rig.run_until(lambda _r: not walking.running, timeout=period / 1000)
    ended_ms = (rig.time - t0) * 1000
    rig.run(WATCH_S)
    held = dict(rig.manager._last_goal)
    lean = math.radians(walking.params.hip_pitch_offset)
    zr, zl = _sole_heights(rig)
    return Halted(
        phase,
        ended_ms if not walking.running else math.inf,
        max(foot_heights(held, lean)) * 1000,
        abs(zr - zl) * 1000,
        rig.world.falls,
        period,
    )


@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_halt_at_any_point_of_a_gait_period_ends_at_double_support_and_never_falls(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("MUJOCO_GL", "disable")
    results = parallel.tries(halt_at, [(k,) for k in range(POINTS)])
    for r in results:
        print(
            f"halt at {r.phase_ms:5.0f} ms: walk ended {r.ended_ms:5.0f} ms later, held soles "
            f"{r.goal_feet_mm:4.1f} mm apart (plant {r.plant_feet_mm:4.1f} mm), falls {r.falls}"
        )
    for r in results:
        assert r.falls == 0, r
        assert r.ended_ms <= r.period_ms / 2 + 8.0 + 1e-6, r  # half a period (and its tick)
        assert r.goal_feet_mm <= FOOT_DOWN_M * 1000, r
        assert r.plant_feet_mm <= PLANT_FOOT_M * 1000, r
