"""Gait steps under bus faults against a clean run, measured in the same run.

    .venv/bin/python benchmarks/fault_walk.py [--seconds 20] [--x 0.05] \
        [--sim-arg=--drop=0.05 --sim-arg=--corrupt=0.01]

Starts `darwin up` twice (no gateway): once clean (the baseline), once with the emulator
dropping and corrupting replies (default 5 % dropped, 1 % corrupt). Each walks forward for
``--seconds`` of wall-clock time and counts the gait's step boundaries
(``status.motion.walking.steps``), alongside the loop's ticks per second and overruns. Gait
time follows the clock, so late ticks cost smoothness, not steps: the ratio should stay near 1.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.fixtures.system import start_system

DEFAULT_FAULTS = ["--drop=0.05", "--corrupt=0.01"]


def walk_steps(sim_args: list[str], seconds: float, x: float) -> dict[str, float]:
    with (
        start_system(sim_args=sim_args, gateway=False) as system,
        system.robot_client(name="fault-walk") as robot,
    ):
        robot.wait_for("status", lambda s: s.state in ("running", "degraded"), timeout=60)
        with robot.control():
            robot.walk(x=x)
            robot.wait_for("status", lambda s: s.motion.get("walking", {}).get("steps", 0) >= 1, 30)
            first = robot.wait_for("status")
            t0 = time.monotonic()
            last = first
            while time.monotonic() - t0 < seconds:
                last = robot.wait_for("status", timeout=10)
            robot.halt()
    span = last.loop["ticks"] - first.loop["ticks"]
    return {
        "steps": last.motion["walking"]["steps"] - first.motion["walking"]["steps"],
        "ticks_per_s": span / seconds,
        "overruns": last.loop.get("overruns", 0) - first.loop.get("overruns", 0),
        "missing": last.bus.get("missing_replies", 0) - first.bus.get("missing_replies", 0),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--x", type=float, default=0.05, help="forward speed, m/s")
    ap.add_argument(
        "--sim-arg", action="append", default=None, help="emulator fault option (repeatable)"
    )
    args = ap.parse_args()
    faults = args.sim_arg or DEFAULT_FAULTS
    clean = walk_steps([], args.seconds, args.x)
    faulty = walk_steps(faults, args.seconds, args.x)
    for name, row in (("clean (baseline)", clean), (" ".join(faults), faulty)):
        print(
            f"{name:28} steps/{args.seconds:.0f} s {row['steps']:4.0f}  "
            f"ticks/s {row['ticks_per_s']:6.1f}  overruns {row['overruns']:5.0f}  "
            f"missing replies {row['missing']:5.0f}"
        )
    if clean["steps"]:
        print(f"steps under faults / clean: {faulty['steps'] / clean['steps']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
