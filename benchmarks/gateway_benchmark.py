"""Legacy gateway: monitor message rate and latency for 1, 10 and 50 clients.

Starts ``darwin up`` (emulator, daemon, gateway) on free loopback ports, sweeps the head pan
joint back and forth so its position changes every tick, and connects N legacy clients that
monitor the motors. A direct Zenoh subscriber (a ``Robot``) in this process is the baseline:

- rate: monitor messages per second per client, against the nominal 1/period;
- latency: the age of the data a client receives: for each head position in a monitor
  message, the time since the Robot saw that position published. A monitor message carries the
  newest sample when it is sent, so this is up to one daemon tick (8 ms) of sampling plus the
  gateway's own cost; the ratio to the 1-client run shows what more clients add.

Run by hand:  .venv/bin/python benchmarks/gateway_benchmark.py [--seconds 5] [--period-ms 50]
"""

from __future__ import annotations

import argparse
import bisect
import contextlib
import json
import math
import selectors
import statistics
import sys
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from clients.robot import Robot  # noqa: E402
from tests.fixtures.system import start_system  # noqa: E402
from tests.legacy_client import LegacyClient  # noqa: E402

HEAD_PAN = 19


@contextlib.contextmanager
def darwin_up() -> Iterator[tuple[str, str, tuple[str, int]]]:
    with start_system(robot=f"bench{uuid.uuid4().hex[:6]}", camera="none", timeout=60) as system:
        assert system.gateway is not None, "darwin up started without its gateway"
        yield system.endpoint, system.robot, system.gateway


class Seen:
    """When each head position (0.1° steps, as legacy shows) was published: the daemon's stamp
    (wall clock, same machine), recorded by the direct subscriber."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.times: dict[float, list[float]] = {}
        self.last: float | None = None

    def on_joints(self, msg) -> None:
        now = msg.stamp
        value = round(math.degrees(msg.position[msg.id.index(HEAD_PAN)]), 1)
        if value != self.last:
            self.last = value
            with self.lock:
                self.times.setdefault(value, []).append(now)

    def since(self, value: float, arrival: float) -> float | None:
        with self.lock:
            times = self.times.get(value)
            if not times:
                return None
            i = bisect.bisect_right(times, arrival)
            return arrival - times[i - 1] if i else None


def sweep(robot: Robot, stop: threading.Event) -> None:
    with robot.control("benchmark sweep"):
        target = math.radians(40)
        while not stop.is_set():
            robot.joint(HEAD_PAN, target, speed=1.0)
            target = -target
            stop.wait(1.6)


def measure(gateway: tuple[str, int], seen: Seen, n: int, seconds: float, period_ms: int):
    clients = [LegacyClient(*gateway, timeout=10.0) for _ in range(n)]
    sel = selectors.DefaultSelector()
    counts = [0] * n
    arrivals: list[tuple[float, float]] = []  # (head position, wall clock at arrival)
    bufs = [b""] * n
    last_head: list[float | None] = [None] * n
    try:
        for i, c in enumerate(clients):
            c.send({"monitor": {"motors": 1, "period": period_ms}})
            c.sock.setblocking(False)
            sel.register(c.sock, selectors.EVENT_READ, i)
        t_start = time.monotonic() + 1.0  # let every client get its first (full) message
        t_end = t_start + seconds
        while (now := time.monotonic()) < t_end:
            for key, _ in sel.select(timeout=0.2):
                i = key.data
                c = clients[i]
                with contextlib.suppress(BlockingIOError):
                    bufs[i] += c.sock.recv(1 << 20)
                arrival = time.time()
                while len(bufs[i]) >= 4:
                    size = c.size_of(bufs[i][:4])
                    if len(bufs[i]) < 4 + size:
                        break
                    body, bufs[i] = bufs[i][4 : 4 + size], bufs[i][4 + size :]
                    if now < t_start:
                        continue
                    counts[i] += 1
                    msg = json.loads(body)
                    for m in msg.get("monitor", {}).get("motors", []):
                        # A motor is resent when its speed or load changed: only a new
                        # position has an age to measure.
                        if m["motor"][0] == HEAD_PAN and m["motor"][1] != last_head[i]:
                            last_head[i] = m["motor"][1]
                            arrivals.append((m["motor"][1], arrival))
    finally:
        for c in clients:
            c.close()
    rates = [k / seconds for k in counts]
    # After the run: every sample the clients saw has reached the direct subscriber by now.
    time.sleep(0.2)
    latencies = [lat for v, t in arrivals if (lat := seen.since(v, t)) is not None]
    return statistics.mean(rates), min(rates), latencies


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seconds", type=float, default=5.0, help="measuring window per run")
    ap.add_argument("--period-ms", type=int, default=50, help="each client's monitoring period")
    ap.add_argument("--clients", default="1,10,50", help="client counts to run")
    args = ap.parse_args()
    nominal = 1000.0 / args.period_ms
    print(f"gateway monitor benchmark: motors, period {args.period_ms} ms ({nominal:g}/s nominal)")
    with darwin_up() as (endpoint, robot_name, gateway), Robot(endpoint, robot_name) as robot:
        seen = Seen()
        robot.wait_for("joints", timeout=30)
        stop = threading.Event()
        with robot.subscribe("joints", seen.on_joints):
            sweeper = threading.Thread(target=sweep, args=(robot, stop), daemon=True)
            sweeper.start()
            base_lat = None
            print(
                f"{'clients':>7} {'rate/s':>8} {'min/s':>7} {'vs nominal':>10} "
                f"{'age p50 ms':>10} {'p95 ms':>7} {'vs 1 client':>11}"
            )
            for n in (int(x) for x in args.clients.split(",")):
                mean_rate, min_rate, lats = measure(gateway, seen, n, args.seconds, args.period_ms)
                lats_ms = sorted(x * 1000 for x in lats)
                p50 = statistics.median(lats_ms) if lats_ms else float("nan")
                p95 = lats_ms[int(0.95 * (len(lats_ms) - 1))] if lats_ms else float("nan")
                base_lat = base_lat if base_lat is not None else p50
                print(
                    f"{n:>7} {mean_rate:>8.1f} {min_rate:>7.1f} {mean_rate / nominal:>10.2f} "
                    f"{p50:>10.1f} {p95:>7.1f} {p50 / base_lat:>11.2f}"
                )
            stop.set()
            sweeper.join(timeout=5)
    return 0


if __name__ == "__main__":
    sys.exit(main())
