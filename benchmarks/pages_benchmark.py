"""What the ``pages`` verb costs the motion thread (its handlers run between bus transactions).

    .venv/bin/python benchmarks/pages_benchmark.py [--repeat 50]

Times each op on a real motion manager with a temporary user library, and, as the baseline
measured in the same run, one ``action`` play (a verb every client already sends). The loop's
budget is one 8 ms tick: an op well under it costs no tick.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from config.loader import load_all, robot_from_dict
from robot_daemon.arbiter.registry import MotionContext, Request
from robot_daemon.arbiter.verbs import motion, pages
from robot_daemon.motion.setup import build_manager

PAGE = {
    "number": 200,
    "name": "bench",
    "step": [{"time": 50, "r_elbow": 30.0, "l_elbow": -30.0, "head_pan": 5.0}] * 7,
}


def timed(fn, repeat: int) -> tuple[float, float]:
    samples = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        samples.append((time.perf_counter() - t) * 1000.0)
    return statistics.median(samples), max(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=50)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as user:
        settings = load_all()
        settings["motion"]["user_library"] = user
        robot = robot_from_dict(settings["robot"])
        manager = build_manager(robot, settings)
        ctx = MotionContext(robot, manager, None, settings, None, lambda *a, **k: None)  # type: ignore[arg-type]

        def call(verb, handler, **fields):
            return lambda: handler(Request(verb, "bench", "bench", fields), ctx)

        def play_then_halt() -> None:
            call("action", motion.action, op="play", page=4)()
            manager.halt()

        rows = [("action play (baseline)", play_then_halt)]
        rows += [
            ("pages list", call("pages", pages.pages, op="list")),
            ("pages get", call("pages", pages.pages, op="get", number=4)),
            ("pages put (file written)", call("pages", pages.pages, op="put", page=PAGE)),
            ("pages reload (nothing changed)", call("pages", pages.pages, op="reload")),
            ("pages export (131 072 bytes)", call("pages", pages.pages, op="export")),
        ]
        print(f"{'op':<34} {'median ms':>10} {'max ms':>8}   (tick budget 8 ms)")
        for name, fn in rows:
            med, worst = timed(fn, args.repeat)
            print(f"{name:<34} {med:10.3f} {worst:8.3f}")


if __name__ == "__main__":
    main()
