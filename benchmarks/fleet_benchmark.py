"""A fleet through one router: 3 simulated robots and 30 observer sessions, against 1 robot with
1 observer (the baseline, same run, same router).

Starts ``darwin router`` on a free loopback port and robots with ``darwin up --router`` (emulator
+ daemon, no gateway, no camera, no wire timing: the robots' own cost is not what is measured).
Observers are client sessions to the router, as a notebook's ``Robot`` is, each following one
robot's ``joints``, ``imu`` and ``status`` (observers spread evenly over the robots), in worker
processes of 10 sessions each so one interpreter's GIL does not become the bottleneck. Figures:

- rate: ``joints`` messages per second per observer, against the tick rate (1 / tick_ms);
  ``robot/s`` is the robots' own tick rate over the window (from the tick numbers) and ``got``
  the smallest share of its robot's ticks an observer received: a loaded machine slows the
  robots themselves, which is not the router's doing;
- latency: receipt time minus the daemon's stamp (same clock: one machine); the stamp is taken
  when the tick sampled the bus, so this includes the tick's own work before it publishes;
- router CPU: the ``darwin router`` process's user + system time over the window, in cores
  (100 % = one core), and the observer processes' together: when ``got`` falls below 1 while
  the router has CPU to spare, the observers' own interpreters (or a loaded machine) are what
  cannot keep up, and Zenoh drops their oldest samples rather than slow anyone else;
- a projection for 20 robots and 200 observers, from the router's measured cost per message.

Run by hand:  .venv/bin/python benchmarks/fleet_benchmark.py [--seconds 10] [--robots 3]
              [--observers 30]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.common import cpu_seconds  # noqa: E402
from config.loader import load_all  # noqa: E402
from schemas.keys import Keys  # noqa: E402
from schemas.messages import decode  # noqa: E402
from tests.fixtures.fleet import start_router  # noqa: E402
from tests.fixtures.system import RunningSystem, start_system  # noqa: E402

TOPICS = ("joints", "imu", "status")
PER_WORKER = 10


# -- observer worker (a child process) -------------------------------------------------------
class Counter:
    def __init__(self) -> None:
        self.counts = dict.fromkeys(TOPICS, 0)
        self.bytes = 0
        self.latency: list[float] = []
        self.ticks: list[int] = []  # the first and last joints tick number seen
        self.stamps: list[float] = []
        self.on = False

    def sample(self, topic: str, sample: Any) -> None:
        if not self.on:
            return
        now = time.time()
        payload = sample.payload.to_bytes()
        self.counts[topic] += 1
        self.bytes += len(payload)
        if topic == "joints":
            msg: Any = decode(payload)
            self.latency.append(now - msg.stamp)
            if not self.ticks:
                self.ticks, self.stamps = [msg.tick, msg.tick], [msg.stamp, msg.stamp]
            self.ticks[1], self.stamps[1] = msg.tick, msg.stamp


def observe(endpoint: str, robots: list[str], sessions: int, seconds: float) -> int:
    """Worker: ``sessions`` client sessions, spread over ``robots``; waits for ``go`` on stdin,
    measures ``seconds``, prints one JSON line per session."""
    import zenoh

    from schemas.session import open_client

    opened: list[zenoh.Session] = []
    counters: list[Counter] = []
    subs: list[Any] = []
    first = threading.Semaphore(0)
    try:
        for i in range(sessions):
            s = open_client(endpoint)
            opened.append(s)
            c = Counter()
            counters.append(c)
            keys = Keys(robots[i % len(robots)])
            seen = threading.Event()

            def cb(sample: Any, topic: str, c: Counter = c, seen: threading.Event = seen) -> None:
                if not seen.is_set():
                    seen.set()
                    first.release()
                c.sample(topic, sample)

            for topic in TOPICS:
                key = keys.topics()[topic]
                subs.append(s.declare_subscriber(key, lambda smp, t=topic, cb=cb: cb(smp, t)))
        for _ in range(sessions):
            first.acquire(timeout=30)
        print("ready", flush=True)
        sys.stdin.readline()  # "go"
        for c in counters:
            c.on = True
        time.sleep(seconds)  # the measuring window
        for c in counters:
            c.on = False
        for c in counters:
            out = {"counts": c.counts, "bytes": c.bytes, "latency": c.latency}
            print(json.dumps({**out, "ticks": c.ticks, "stamps": c.stamps}))
        sys.stdout.flush()
    finally:
        for s in opened:
            with contextlib.suppress(Exception):
                s.close()
    return 0


# -- the parent -------------------------------------------------------------------------------
def pct(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    values = sorted(values)
    return values[min(len(values) - 1, int(q * len(values)))]


def add_robot(stack: contextlib.ExitStack, router: str) -> RunningSystem:
    name = f"bench{uuid.uuid4().hex[:6]}"
    up = start_system(robot=name, router=router, gateway=False, wire_timing=False, timeout=90)
    return stack.enter_context(up)


def run(router_ep: str, router_pid: int, names: list[str], observers: int, seconds: float) -> dict:
    """One measurement: ``observers`` sessions over ``names``; per-session results and the
    router's CPU over the window."""
    workers = []
    for start in range(0, observers, PER_WORKER):
        n = min(PER_WORKER, observers - start)
        # Each worker's sessions start at its own offset, so observers spread over the robots.
        mine = names[start % len(names) :] + names[: start % len(names)]
        cmd = [sys.executable, __file__, "--observe", router_ep, "--robot-names", ",".join(mine),
               "--sessions", str(n), "--seconds", str(seconds)]  # fmt: skip
        workers.append(
            subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        )
    try:
        for w in workers:
            assert w.stdout is not None and w.stdout.readline().strip() == "ready", "worker died"
        cpu0, t0 = cpu_seconds(router_pid), time.monotonic()
        wcpu0 = sum(cpu_seconds(w.pid) for w in workers)
        for w in workers:
            assert w.stdin is not None
            w.stdin.write("go\n")
            w.stdin.flush()
        results = []
        wcpu1 = 0.0
        for w in workers:
            assert w.stdout is not None
            results.append(json.loads(w.stdout.readline()))
            wcpu1 += cpu_seconds(w.pid)  # before it reports the rest and closes its sessions
            results += [json.loads(line) for line in w.stdout]
        cpu1, t1 = cpu_seconds(router_pid), time.monotonic()
    finally:
        for w in workers:
            with contextlib.suppress(subprocess.TimeoutExpired):
                w.wait(timeout=30)
    # The window is the workers' (seconds); the router's CPU is over the same span, give or take
    # the workers' start and report, so it is divided by the wall time it was measured over.
    return {
        "sessions": results,
        "router_cores": (cpu1 - cpu0) / (t1 - t0),
        "observer_cores": (wcpu1 - wcpu0) / seconds,
        "seconds": seconds,
    }


def summarise(label: str, res: dict, robots_n: int, tick_hz: float) -> dict[str, float]:
    s = res["sessions"]
    secs = res["seconds"]
    rates = [x["counts"]["joints"] / secs for x in s]
    # What reached each observer of the ticks its robot published meanwhile (tick numbers), and
    # the robots' own tick rate (a loaded machine slows the robots, not only the delivery).
    delivered = [x["counts"]["joints"] / (x["ticks"][1] - x["ticks"][0] + 1) for x in s]
    robot_hz = [(x["ticks"][1] - x["ticks"][0]) / (x["stamps"][1] - x["stamps"][0]) for x in s]
    lat = [v for x in s for v in x["latency"]]
    out_msgs = sum(sum(x["counts"].values()) for x in s) / secs
    out_bytes = sum(x["bytes"] for x in s) / secs
    per_robot = sum(sum(x["counts"].values()) for x in s) / secs / len(s)  # one robot's topics
    in_msgs = per_robot * robots_n
    fig = {
        "rate_mean": sum(rates) / len(rates),
        "rate_min": min(rates),
        "delivered_min": min(delivered),
        "delivered_mean": sum(delivered) / len(delivered),
        "robot_hz": sum(robot_hz) / len(robot_hz),
        "p50_ms": pct(lat, 0.5) * 1000,
        "p99_ms": pct(lat, 0.99) * 1000,
        "router_cores": res["router_cores"],
        "observer_cores": res["observer_cores"],
        "in_msgs": in_msgs,
        "out_msgs": out_msgs,
        "out_mb": out_bytes / 1e6,
        "msg_bytes": out_bytes / out_msgs if out_msgs else 0.0,
        "per_robot_msgs": per_robot,
    }
    print(
        f"{label:<22} {fig['rate_mean']:>7.1f} {fig['rate_min']:>7.1f} "
        f"{fig['rate_mean'] / tick_hz:>6.2f} {fig['robot_hz']:>7.1f} {fig['delivered_min']:>6.3f} "
        f"{fig['p50_ms']:>7.2f} {fig['p99_ms']:>7.2f} "
        f"{fig['router_cores'] * 100:>8.1f}% {fig['observer_cores'] * 100:>8.1f}% "
        f"{fig['out_msgs']:>9.0f} {fig['out_mb']:>7.2f}"
    )
    return fig


def project(base: dict[str, float], fleet: dict[str, float], robots_n: int, obs_n: int) -> None:
    # Router cost per message handled (one in from a robot or one out to an observer), from the
    # fleet run with its fixed costs included: an overestimate rather than an underestimate.
    handled = fleet["in_msgs"] + fleet["out_msgs"]
    per_msg_us = fleet["router_cores"] / handled * 1e6 if handled else float("nan")
    base_handled = max(1.0, base["in_msgs"] + base["out_msgs"])
    base_us = base["router_cores"] / base_handled * 1e6
    # What one robot publishes: what the baseline observer got, scaled by the share it got.
    per_robot = base["per_robot_msgs"] / base["delivered_mean"]
    in_msgs = robots_n * per_robot
    out_msgs = obs_n * per_robot
    cores = (in_msgs + out_msgs) * per_msg_us / 1e6
    mbps = out_msgs * fleet["msg_bytes"] * 8 / 1e6
    print(
        f"\nprojection for {robots_n} robots and {obs_n} observers (each following one robot's "
        f"joints, imu and status):\n"
        f"  router cost measured: {per_msg_us:.1f} µs CPU per message handled "
        f"(baseline run: {base_us:.1f} µs)\n"
        f"  messages: {in_msgs:,.0f}/s in from robots ({per_robot:.0f}/s each), "
        f"{out_msgs:,.0f}/s out to observers\n"
        f"  router CPU: ~{cores:.2f} cores; observer traffic out of the router: "
        f"~{mbps:.0f} Mbit/s ({fleet['msg_bytes']:.0f} B per message on average)\n"
        "  assumptions: router cost linear in messages handled (routing fan-out, no per-session\n"
        "  fixed cost beyond that); observers spread evenly, none subscribing to the camera\n"
        "  (a 30 fps JPEG stream per watched robot adds its frames × observers); robots on\n"
        "  their own machines (here they share the router's cores, so the figures are\n"
        "  pessimistic); one router: past ~1 core, use one router per group of robots, or\n"
        "  observers that follow status only (10/s instead of ~260/s)."
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seconds", type=float, default=10.0, help="measuring window per run")
    ap.add_argument("--robots", type=int, default=3)
    ap.add_argument("--observers", type=int, default=30)
    ap.add_argument("--observe", metavar="ENDPOINT", help=argparse.SUPPRESS)
    ap.add_argument("--robot-names", help=argparse.SUPPRESS)
    ap.add_argument("--sessions", type=int, default=1, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.observe:
        return observe(args.observe, args.robot_names.split(","), args.sessions, args.seconds)

    tick_hz = 1000.0 / float(load_all()["daemon"]["tick_ms"])
    print(
        f"fleet benchmark: observers through one darwin router, {args.seconds:g} s windows, "
        f"tick rate {tick_hz:g}/s"
    )
    with start_router() as router, contextlib.ExitStack() as stack:
        pid = router.process.pid
        # The baseline runs before the other robots join: the router then carries one robot.
        names = [add_robot(stack, router.endpoint).robot]
        print(
            f"{'run':<22} {'rate/s':>7} {'min/s':>7} {'/tick':>6} {'robot/s':>7} {'got':>6} "
            f"{'p50 ms':>7} {'p99 ms':>7} "
            f"{'router':>9} {'observers':>9} {'out msg/s':>9} {'MB/s':>7}"
        )
        base = summarise(
            "1 robot, 1 observer", run(router.endpoint, pid, names[:1], 1, args.seconds), 1,
            tick_hz,
        )  # fmt: skip
        names += [add_robot(stack, router.endpoint).robot for _ in range(args.robots - 1)]
        label = f"{args.robots} robots, {args.observers} obs"
        res = run(router.endpoint, pid, names, args.observers, args.seconds)
        fleet = summarise(label, res, args.robots, tick_hz)
        # What the robots published into the router (observers may have received less).
        published = base["per_robot_msgs"] / base["delivered_mean"]
        fleet["in_msgs"] = args.robots * published * fleet["robot_hz"] / base["robot_hz"]
        print(
            f"{'vs baseline':<22} {fleet['rate_mean'] / base['rate_mean']:>7.2f} "
            f"{fleet['rate_min'] / base['rate_mean']:>7.2f} {'':>6} "
            f"{fleet['robot_hz'] / base['robot_hz']:>7.2f} {'':>6} "
            f"{fleet['p50_ms'] / base['p50_ms']:>7.2f} {fleet['p99_ms'] / base['p99_ms']:>7.2f} "
            f"{fleet['router_cores'] / max(base['router_cores'], 1e-9):>8.1f}×"
        )
        project(base, fleet, 20, 200)
    return 0


if __name__ == "__main__":
    sys.exit(main())
