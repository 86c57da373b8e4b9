"""Ball play closed in physics: the MuJoCo plant under the emulator, the head camera drawn by
MuJoCo (OpenCV where no GL), the daemon's ball finder, motion modules and bus code on top
(``SimRig``), lock-step on a simulated clock.

20 random starts (seeded): the ball 0.3–1.0 m away in any direction. A start counts when play
ends "done", the robot never fell, a foot touched the ball (a MuJoCo contact: the kick moves the
ball by contact, nothing places it), the ball lay still until the kick began and ended at least
``MOVED_M`` from where it lay. At least 16 of 20 must count (the long tier, ``-m long``; the
default run plays the first 4 and needs 3); the median time to the kick is printed (``-s``).
The runs are independent and share the machine's cores (:mod:`.parallel`).

What made the robot kick standing (issue 18; before, 0 of 5): played from the walk-ready stance,
the stock page 12 shifts the body's centre of mass to 17 mm inside the standing sole's centre
(its edge 33 mm out), and as the kicking foot lifts the standing hip roll and ankle roll give
~6° and ~4° under ~1.3 and ~0.9 N·m at the identified stiffness (P 32 → 12.6 N·m/rad), so the
robot rolled over the kicking side. Now (each measured alone first, see the page files):
the action player applies a page's per-joint slopes as P gains as the framework's Action.cpp
does, and the kick pages give the standing leg's roll joints slope 0x33 (P 128), lean both legs
4° further over the standing foot and shift the weight in 100 time units instead of 62 (the
quick shift rocked the standing foot from edge to edge after walking); ball play stands
``kick_settle_s`` after the walk's last step before the page starts (config/ballplay.toml).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from config.loader import load_all
from tests.fixtures.sim_rig import SimRig
from tests.physics.parallel import tries

RUNS = 20
NEEDED = 16
PLAY_S = 45.0
MOVED_M = 0.2  # the ball's travel from where it lay that counts as kicked


@dataclass
class Run:
    ok: bool
    phase: str
    falls: int
    touches: int
    moved_m: float
    kick_s: float  # from the start of play to the kick phase (nan: no kick)
    ball_still_before_kick: bool


def ball_xy(rig: SimRig) -> np.ndarray:
    ball = rig.world.snapshot().ball  # the snapshot reads the ball's body now
    return np.array([ball["x"], ball["y"]])


def ball_speed(rig: SimRig) -> float:
    ball = rig.world.snapshot().ball
    return math.hypot(ball["vx"], ball["vy"])


def one_run(seed: int, dist: float, bearing: float) -> Run:
    rig = SimRig(seed=seed, settings=load_all(), physics="mujoco")
    rig.world.place_robot(0.0, 0.0, 0.0)
    rig.world.place_ball(dist * math.cos(bearing), dist * math.sin(bearing))
    rig.run(0.3)
    lay = ball_xy(rig)
    t0 = rig.time
    kick_s = math.nan
    still = True

    def watch(r: SimRig) -> bool:
        nonlocal kick_s, still
        if math.isnan(kick_s):
            if r.ball_play.phase == "kicking":
                kick_s = r.time - t0
            elif np.linalg.norm(ball_xy(r) - lay) > 0.05:
                still = False  # pushed before any kick: walked into it
        return not r.ball_play.playing

    rig.ball_play.start()
    rig.run_until(watch, timeout=PLAY_S)
    rig.run_until(lambda r: ball_speed(r) < 0.01, timeout=5.0)
    moved = float(np.linalg.norm(ball_xy(rig) - lay))
    ok = (
        rig.ball_play.phase == "done"
        and rig.world.falls == 0
        and rig.world.ball.touches > 0
        and moved > MOVED_M
        and still
    )
    return Run(
        ok, rig.ball_play.phase, rig.world.falls, rig.world.ball.touches, moved, kick_s, still
    )


@pytest.mark.slow
@pytest.mark.timeout(2400)
@pytest.mark.parametrize(
    "count, needed",
    # The first four of the same starts (near and far, ahead and behind) in the default run;
    # all twenty in the long tier (-m long).
    [
        pytest.param(4, 3, id="four-starts"),
        pytest.param(RUNS, NEEDED, id="twenty-starts", marks=pytest.mark.long),
    ],
)
def test_ball_play_kicks_the_ball_from_random_starts_in_physics(count: int, needed: int) -> None:
    rng = np.random.default_rng(18)
    starts = [
        (1800 + k, float(rng.uniform(0.3, 1.0)), float(rng.uniform(-math.pi, math.pi)))
        for k in range(RUNS)
    ][:count]
    runs = tries(one_run, starts)
    wins = [r for r in runs if r.ok]
    kicks = [r.kick_s for r in wins]
    print(
        f"\nball play in physics: {len(wins)}/{len(runs)} kicked"
        + (f", median time to the kick {float(np.median(kicks)):.1f} s" if kicks else "")
    )
    for k, r in enumerate(runs):
        print(
            f"  run {k}: {r.phase}, falls {r.falls}, touches {r.touches}, "
            f"ball moved {r.moved_m:.2f} m, kick at {r.kick_s:.1f} s"
        )
    assert len(wins) >= needed, f"ball play kicked {len(wins)} of {len(runs)} starts in physics"
