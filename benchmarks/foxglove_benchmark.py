"""Foxglove server: what it costs the robot daemon, with 0, 1 and 10 clients subscribed to
everything, against no server at all in the same run; and the server's own CPU.

Starts ``darwin up --camera sim`` (emulator, daemon) on free loopback ports. For each
configuration it measures, over the same window:

- the daemon's loop period p50 / p99 / max, from the daemon's own statistics (``status.loop``
  at the end of the window: a rolling window of recent ticks) and from the spacing of the
  ``joints`` stamps a direct subscriber sees (p99 of the inter-stamp period);
- the daemon's CPU (its process, from /proc, in % of one core);
- the Foxglove server's CPU and the messages each client received per second.

"none" runs without a server process; "0" runs the server with no client connected. Clients
are Python protocol clients (tests/foxglove_ws.py) in this process, subscribed to every channel
including the camera, so the daemon captures frames from 1 client on.

Run by hand:  .venv/bin/python benchmarks/foxglove_benchmark.py [--seconds 5] [--clients 0,1,10]
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import statistics
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.common import cpu_seconds  # noqa: E402
from clients.robot import Robot  # noqa: E402
from tests.fixtures.system import spawn_darwin, start_system, stop_group  # noqa: E402
from tests.foxglove_ws import FoxgloveClient  # noqa: E402


def find_child(parent: int, needle: str) -> int:
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        with contextlib.suppress(OSError):
            stat = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
            if int(stat[1]) == parent and needle in cmd:
                return int(entry.name)
    raise RuntimeError(f"no child of {parent} running {needle!r}")


def start(args: list[str], prefix: str) -> tuple[subprocess.Popen[str], str]:
    proc = spawn_darwin(*args, stderr=subprocess.DEVNULL)
    assert proc.stdout is not None
    for line in proc.stdout:
        if line.startswith(prefix):
            threading.Thread(target=proc.stdout.read, daemon=True).start()
            return proc, line.split(" ", 1)[1].strip()
    raise RuntimeError(f"darwin {args[0]} exited before printing {prefix!r}")


@contextlib.contextmanager
def darwin_up() -> Iterator[tuple[str, str, int]]:
    robot = f"bench{uuid.uuid4().hex[:6]}"
    with start_system(robot=robot, camera="sim", gateway=False) as system:
        yield (
            system.endpoint,
            robot,
            find_child(system.process.pid, "robot_daemon.launch.cli daemon"),
        )


def pump(client: FoxgloveClient, stop_: threading.Event, counts: list[int], i: int) -> None:
    while not stop_.is_set():
        try:
            frame = client.ws.recv(timeout=0.2)
        except TimeoutError:
            continue
        except Exception:
            return
        if isinstance(frame, bytes):
            counts[i] += 1


def measure(robot: Robot, daemon: int, server: int | None, url: str | None, n: int, seconds: float):
    clients = [FoxgloveClient.open(url) for _ in range(n)] if url else []
    for c in clients:
        c.subscribe(*c.topics())
    counts = [0] * n
    halt = threading.Event()
    pumps = [
        threading.Thread(target=pump, args=(c, halt, counts, i), daemon=True)
        for i, c in enumerate(clients)
    ]
    for p in pumps:
        p.start()
    stamps: list[float] = []
    try:
        time.sleep(1.0)  # settle: subscriptions reach the daemon, the camera starts
        for i in range(n):
            counts[i] = 0
        d0, s0 = cpu_seconds(daemon), cpu_seconds(server) if server else 0.0
        t0 = time.monotonic()
        with robot.subscribe("joints", lambda m: stamps.append(m.stamp)):
            time.sleep(seconds)  # the measuring window itself
        elapsed = time.monotonic() - t0
        d1, s1 = cpu_seconds(daemon), cpu_seconds(server) if server else 0.0
        loop = robot.wait_for("status", timeout=5).loop
    finally:
        halt.set()
        for p in pumps:
            p.join(timeout=2)
        for c in clients:
            c.close()
    gaps = sorted((b - a) * 1000 for a, b in itertools.pairwise(stamps))
    p99 = gaps[int(0.99 * (len(gaps) - 1))] if gaps else float("nan")
    rate = statistics.mean(counts) / elapsed if counts else 0.0
    return {
        "p50": loop.get("period_p50_ms", float("nan")),
        "p99": loop.get("period_p99_ms", float("nan")),
        "max": loop.get("period_max_ms", float("nan")),
        "gap_p99": p99,
        "daemon_cpu": 100 * (d1 - d0) / elapsed,
        "server_cpu": 100 * (s1 - s0) / elapsed if server else float("nan"),
        "rate": rate,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seconds", type=float, default=5.0, help="measuring window per run")
    ap.add_argument("--clients", default="0,1,10", help="client counts to run")
    args = ap.parse_args()
    counts = [int(x) for x in args.clients.split(",")]
    print(f"foxglove benchmark: {args.seconds:g} s per run, clients subscribed to every channel")
    header = (
        f"{'server':>8} {'p50 ms':>7} {'p99 ms':>7} {'max ms':>7} {'gap p99':>8} "
        f"{'daemon %':>9} {'vs none':>7} {'server %':>9} {'msg/s/cl':>9}"
    )
    with darwin_up() as (endpoint, robot_name, daemon), Robot(endpoint, robot_name) as robot:
        robot.wait_for("joints", timeout=30)
        base = measure(robot, daemon, None, None, 0, args.seconds)
        print(header)
        row("none", base, base)
        fox, url = start(
            ["foxglove", "--connect", endpoint, "--robot", robot_name, "--listen", "127.0.0.1:0"],
            "foxglove:",
        )
        try:
            for n in counts:
                row(f"{n} cl", measure(robot, daemon, fox.pid, url, n, args.seconds), base)
        finally:
            stop_group(fox)
        row("none", measure(robot, daemon, None, None, 0, args.seconds), base)
    return 0


def row(name: str, r: dict[str, float], base: dict[str, float]) -> None:
    print(
        f"{name:>8} {r['p50']:>7.2f} {r['p99']:>7.2f} {r['max']:>7.2f} {r['gap_p99']:>8.2f} "
        f"{r['daemon_cpu']:>9.1f} {r['daemon_cpu'] / base['daemon_cpu']:>7.2f} "
        f"{r['server_cpu']:>9.1f} {r['rate']:>9.0f}",
        flush=True,
    )


if __name__ == "__main__":
    sys.exit(main())
