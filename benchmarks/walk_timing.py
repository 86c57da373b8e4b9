"""Walk timing on the emulator: the achieved gait period and step timing, measured from the
joint trajectories the daemon publishes, against the configured period (the baseline).

    .venv/bin/python benchmarks/walk_timing.py [--seconds 8] [--x 0.08]

Starts its own `darwin up` (emulator with wire timing, daemon), walks forward, records
``…/joints``, and finds each foot's lift-off (sole > 15 mm above the other) in the goals the
daemon sent and in the positions the emulated servos reported (gyro feedback off, so the
emulated IMU's noise does not move the feet). Prints periods in ticks and in
wall-clock seconds (from message stamps), the left→right step offset, and ratios.
"""

from __future__ import annotations

import argparse
import itertools
import math
import queue
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from config.loader import load_all, load_robot
from robot_daemon.motion.walking.gait import foot_heights
from tests.fixtures.system import start_system


def lift_offs(samples: list[tuple[int, float, tuple[float, float]]], foot: int):
    out = []
    for (_, _, a), (tick, stamp, b) in itertools.pairwise(samples):
        if b[foot] > 0.015 >= a[foot]:
            out.append((tick, stamp))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--x", type=float, default=0.08, help="forward speed, m/s")
    args = ap.parse_args()
    params = load_all()["walking"]
    ids = list(load_robot().ids)
    lean = math.radians(params["hip_pitch_offset"])
    period_s = params["period_time"] / 1000
    with start_system(gateway=False) as system, system.robot_client(name="bench") as robot:
        robot.wait_for("joints", timeout=30)
        robot.acquire()
        # Gyro feedback reacts to the emulated IMU's noise and moves the feet by a few mm, which
        # blurs the lift-off detection: measure the gait's own timing with it off.
        robot.command("walk_params", set={"balance_enable": False})
        got: queue.Queue = queue.Queue()
        sub = robot.subscribe("joints", got.put)
        robot.walk(x=args.x)
        robot.wait_for("status", lambda s: s.motion.get("walking", {}).get("steps", 0) >= 3, 30)
        while not got.empty():
            got.get_nowait()
        msgs = []
        first = got.get(timeout=10)
        msgs.append(first)
        while msgs[-1].stamp - first.stamp < args.seconds:
            msgs.append(got.get(timeout=10))
        robot.walk_stop()
        sub.close()
        robot.command("halt")
        robot.release()
    rows = {}
    for source in ("goal", "position"):
        samples = []
        for m in msgs:
            vals = getattr(m, source)
            samples.append(
                (m.tick, m.stamp, foot_heights({j: vals[ids.index(j)] for j in range(7, 19)}, lean))
            )
        rows[source] = (lift_offs(samples, 0), lift_offs(samples, 1))
    ticks = [m.tick for m in msgs]
    tick_s = statistics.mean(
        (b.stamp - a.stamp) / (b.tick - a.tick)
        for a, b in itertools.pairwise(msgs)
        if b.tick > a.tick
    )
    print(
        f"recorded {len(msgs)} joint messages over {msgs[-1].stamp - msgs[0].stamp:.2f} s, "
        f"ticks {ticks[0]}..{ticks[-1]} (missing {ticks[-1] - ticks[0] + 1 - len(set(ticks))}); "
        f"mean tick {tick_s * 1000:.2f} ms (nominal 8.00)"
    )
    print(f"configured period {period_s * 1000:.0f} ms = {period_s / 0.008:.1f} ticks (baseline)")
    for source, (right, left) in rows.items():
        for name, offs in (("right", right), ("left", left)):
            if len(offs) < 2:
                print(f"{source:8} {name:5}: fewer than two lift-offs")
                continue
            dt_ticks = [b[0] - a[0] for a, b in itertools.pairwise(offs)]
            dt_s = [b[1] - a[1] for a, b in itertools.pairwise(offs)]
            print(
                f"{source:8} {name:5}: period {statistics.mean(dt_ticks):.2f} ticks "
                f"(min {min(dt_ticks)}, max {max(dt_ticks)}), "
                f"{statistics.mean(dt_s) * 1000:.1f} ms wall, ratio to configured "
                f"{statistics.mean(dt_s) / period_s:.3f}"
            )
        if right and left:
            offsets = [
                (r[0] - l_[0]) % round(period_s / 0.008) for l_, r in zip(left, right, strict=False)
            ]
            print(
                f"{source:8} step offset left→right: {offsets} ticks (half period "
                f"{period_s / 0.016:.1f})"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
