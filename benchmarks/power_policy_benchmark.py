"""The battery and heat policy's cost (robot_daemon/engine/power_actions.py), against the status
message the daemon encodes at the same 10 Hz, both measured here in this run.

    .venv/bin/python benchmarks/power_policy_benchmark.py --runs 20000

1. Baseline: ``encode(Status(...))`` of a full status (what ``_publish_status`` hands on).
2. The policy: ``PowerGuard.check`` with 20 servos and a voltage with nothing to do (the
   common case), then with values moving across the thresholds.

Prints µs of process CPU time per call, the ratio policy / baseline, and the cost per 8 ms tick
once spread over the 12.5 ticks of a status period.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from config.loader import load_all, robot_from_dict
from robot_daemon.engine.power_actions import PowerGuard
from robot_daemon.motion.setup import build_manager
from schemas.messages import Status, encode


def _per_call(fn, runs: int) -> float:
    t0 = time.process_time()
    for i in range(runs):
        fn(i)
    return (time.process_time() - t0) / runs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20000)
    args = parser.parse_args()
    settings = load_all()
    robot = robot_from_dict(settings["robot"])
    manager = build_manager(robot, settings)
    events: list[tuple] = []
    guard = PowerGuard(robot, settings, manager, None, lambda *a, **k: events.append(a))
    temps = np.full(256, 41.0)
    online = np.ones(256, dtype=bool)
    status = Status(
        state="running",
        robot="op1",
        motion=manager.status(),
        loop={"tick_ms": 8.0, "period_p50_ms": 8.0, "overruns": 0},
        voltage=12.1,
        power=guard.status()[0],
        heat=guard.status()[1],
    )

    base = _per_call(lambda i: encode(status), args.runs)
    quiet = _per_call(lambda i: guard.check(12.1, temps, online, i / 10), args.runs)
    # Values wandering around the warn thresholds (inside the hold and the hysteresis).
    wobble = [12.1, 11.05, 10.95, 11.2]
    moving = _per_call(
        lambda i: guard.check(wobble[i % 4], temps + (i % 7), online, i / 10), args.runs
    )
    tick = 1 / 12.5
    for name, cost in (
        ("status encode", base),
        ("policy, quiet", quiet),
        ("policy, moving", moving),
    ):
        print(f"{name}: {cost * 1e6:.1f} µs/call, {cost * tick * 1e6:.2f} µs per 8 ms tick")
    print(f"ratio quiet/status: {quiet / base:.2f}")
    print(f"ratio moving/status: {moving / base:.2f}")
    print(f"events: {len(events)}")


if __name__ == "__main__":
    main()
