"""Ball play on the simulator from random start poses: success rate and time to kick.

    .venv/bin/python benchmarks/ballplay_benchmark.py --runs 20 --seed 1 [--stock]

Each run places the robot at the field centre and the ball at a random distance (0.3..1.5 m)
and bearing (any direction, behind included), starts ball play and steps the simulated robot
(``SimRig``: servo dynamics, world, the daemon's bus code over the in-process link, its motion
modules, the ball finder on rendered frames) until play ends or 90 simulated seconds pass. A run
succeeds when play ends "done", the robot has not fallen and the ball ends farther from the
robot than it started. Figures: success
rate, median and worst simulated time to the kick, and the simulation's speed against real time
(the baseline measured in the same run: 1.0 = real time).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # for tests.shared_data

from config.loader import load_all
from tests.fixtures.sim_rig import SimRig
from tests.shared_data import STOCK_MOTIONS


def one_run(seed: int, rng: np.random.Generator, library: str | None) -> dict[str, float | str]:
    settings = load_all()
    if library:
        settings.setdefault("motion", {})["library"] = library
    rig = SimRig(seed=seed, settings=settings)
    dist = float(rng.uniform(0.3, 1.5))
    bearing = float(rng.uniform(-math.pi, math.pi))
    rig.world.place_robot(0.0, 0.0, 0.0)
    rig.world.place_ball(dist * math.cos(bearing), dist * math.sin(bearing))
    rig.run(0.3)
    start_d = rig.world.ball_distance() or 0.0
    kick_t = math.nan
    t0 = rig.time
    wall = time.perf_counter()
    rig.ball_play.start()

    def done(r: SimRig) -> bool:
        nonlocal kick_t
        if math.isnan(kick_t) and r.ball_play.phase == "kicking":
            kick_t = r.time - t0
        return not r.ball_play.playing

    rig.run_until(done, timeout=90.0)
    ball = rig.world.ball.state
    rig.run_until(lambda r: ball is None or ball.speed == 0.0, timeout=10.0)
    sim_s = rig.time - t0
    wall_s = time.perf_counter() - wall
    end_d = rig.world.ball_distance() or 0.0
    ok = rig.ball_play.phase == "done" and rig.world.falls == 0 and end_d > start_d
    return {
        "ok": "yes" if ok else "no",
        "phase": rig.ball_play.phase,
        "falls": rig.world.falls,
        "bearing_deg": math.degrees(bearing),
        "start_m": start_d,
        "end_m": end_d,
        "kick_s": kick_t,
        "sim_s": sim_s,
        "wall_s": wall_s,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--seed", type=int, default=1)
    which = parser.add_mutually_exclusive_group()
    which.add_argument(
        "--library",
        default=None,
        help="motion file or folder with the kick pages (default: the project's own library)",
    )
    which.add_argument(
        "--stock",
        action="store_true",
        help=f"kick with the stock ROBOTIS pages ({STOCK_MOTIONS})",
    )
    args = parser.parse_args(argv)
    if args.stock:
        if not STOCK_MOTIONS.exists():
            parser.error(f"no stock motion file at {STOCK_MOTIONS} (set DARWIN_SHARED_DATA)")
        args.library = str(STOCK_MOTIONS)
    rng = np.random.default_rng(args.seed)
    rows = []
    print(
        f"{'run':>3} {'ok':>3} {'phase':>8} {'bearing':>8} {'start':>6} {'end':>6} "
        f"{'kick@':>6} {'sim s':>6} {'wall s':>6}"
    )
    for k in range(args.runs):
        r = one_run(args.seed * 1000 + k, rng, args.library)
        rows.append(r)
        print(
            f"{k:3d} {r['ok']:>3} {r['phase']:>8} {r['bearing_deg']:8.0f} {r['start_m']:6.2f} "
            f"{r['end_m']:6.2f} {r['kick_s']:6.1f} {r['sim_s']:6.1f} {r['wall_s']:6.1f}",
            flush=True,
        )
    wins = [r for r in rows if r["ok"] == "yes"]
    kicks = [float(r["kick_s"]) for r in wins]
    sim = sum(float(r["sim_s"]) for r in rows)
    wall = sum(float(r["wall_s"]) for r in rows)
    print()
    print(f"success: {len(wins)}/{len(rows)} = {100.0 * len(wins) / len(rows):.0f} %")
    if kicks:
        print(
            f"time to kick (simulated s): median {statistics.median(kicks):.1f}, "
            f"max {max(kicks):.1f}"
        )
    print(f"falls: {sum(int(r['falls']) for r in rows)}")
    print(
        f"simulation speed: {sim / wall:.2f}× real time (baseline 1.0 = real time; "
        f"{sim:.0f} simulated s in {wall:.0f} s)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
