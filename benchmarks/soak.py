"""A fleet soak with chaos: three simulated robots on one authenticated router, with every kind
of client, while something is killed and started again every period.

    python benchmarks/soak.py --minutes 60          # the hour; --minutes 5 is the CI form

Runs: ``darwin router --auth``; robots s1, s2, s3 (``darwin up --router … --user sN``; s3 in a
network namespace of its own, behind a link the chaos cuts and impairs with ``tc netem``, when
namespaces are available — root and iproute2); a TUI-like observer and a notebook-like driver
(``benchmarks/soak_children.py``); ``darwin record`` of s2's status; ``darwin gateway`` for s1
with a legacy TCP client; ``darwin foxglove`` (s2) and ``darwin ros2`` (s3).

Every period (60 s, or minutes × 3 s in short runs, at least 15 s) the chaos kills (SIGKILL) and
starts again, in turn: an adapter, a client, the router, s3's link (cut, or 30 % loss and 100 ms
delay, for a third of a period). At the end it prints, one ``name: value`` a line (``--json``:
one object):

- ``lease_stops_missed``: kills of the driver while it held s1's lease after which the observer
  did not see the lease free within ``LEASE_STOP_S`` (the link lease, 3 s, plus slack) — must be 0;
- ``stuck``: processes that did not print their ready line when started again, or did not end
  within 15 s of SIGTERM at the end — must be 0;
- ``recorded`` / ``published``: s2's status messages in the recording against those a separate
  subscriber counted while the recorder ran; the recorder writes every 0.5 s (``--flush``) and
  closes the file on SIGTERM, so nothing is documented to be lost but what crossed the start and
  stop instants (``record_window``, one status period each side);
- per process group: memory (RSS, MiB), threads and open sockets (the Zenoh sessions and links)
  at start and end, and their growth per hour;
- ``longest_unlisted_s``: after each router restart, how long until the observer listed all three
  robots again; the longest.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from benchmarks.soak_procs import Proc, group_usage  # noqa: E402
from schemas.session import free_tcp_port  # noqa: E402

ROBOTS = ("s1", "s2", "s3")
LEASE_STOP_S = 15.0
READY_S = 90.0
USERS = {**{r: "robot" for r in ROBOTS}, "obs": "observer", "op": "operator", "gw": "operator",
         "fox": "observer", "ros": "observer", "rec": "observer"}


def darwin(*args: str) -> list[str]:
    return [sys.executable, "-m", "robot_daemon.launch.cli", *args]


def child(kind: str, where: str, robot: str, user: str, pw: Path) -> list[str]:
    return [sys.executable, "-m", "benchmarks.soak_children", kind, where, robot, user, str(pw)]


@dataclass
class Soak:
    minutes: float
    period: float
    directory: Path
    net: Any = None  # tests.fixtures.netns.Network, or None: everything on loopback
    procs: dict[str, Proc] = field(default_factory=dict)
    figures: dict[str, Any] = field(default_factory=dict)
    stuck: list[str] = field(default_factory=list)
    lease_checks: int = 0
    lease_missed: int = 0
    unlisted: list[float] = field(default_factory=list)

    def pw(self, user: str) -> Path:
        return self.directory / f"{user}.pw"

    def start(self, name: str, cmd: list[str], ready: str, ns: str | None = None) -> Proc:
        proc = Proc(name, cmd, ready, self.net, ns)
        proc.start()
        self.procs[name] = proc
        if not proc.wait_ready(READY_S):
            raise RuntimeError(f"{name} did not start: {proc.tail()}")
        return proc

    def restart(self, name: str) -> None:
        proc = self.procs[name]
        proc.kill()
        proc.start()
        if not proc.wait_ready(READY_S):
            self.stuck.append(f"{name} (not ready after a restart: {proc.tail()})")

    # -- the fleet -------------------------------------------------------------------------
    def setup(self) -> None:
        for user, role in USERS.items():
            self.pw(user).write_text(f"{user}-soak-password\n")
            done = subprocess.run(darwin("users", "add", user, "--role", role, "--password-file",
                                         str(self.pw(user)), "--users", str(self.users)),
                                  capture_output=True, text=True, cwd=REPO)
            if done.returncode != 0:
                raise RuntimeError(done.stderr)
        port = free_tcp_port()
        host = "0.0.0.0" if self.net else "127.0.0.1"
        self.start("router", darwin("router", "--listen", f"tcp/{host}:{port}", "--auth",
                                    str(self.users)), "router:", "router")
        self.ep = f"tcp/127.0.0.1:{port}"
        for robot in ROBOTS:
            ns, ep = "router", self.ep
            if self.net and robot == "s3":
                ns, ep = "s3", f"tcp/{self.net.router_addr('s3')}:{port}"
            self.start(robot, darwin("up", "--router", ep, "--robot", robot, "--user", robot,
                                     "--password-file", str(self.pw(robot)), "--no-gateway",
                                     "--camera", "none"), "robot:", ns)
        login = lambda u: ["--user", u, "--password-file", str(self.pw(u))]  # noqa: E731
        # A fixed port: the legacy client finds the gateway again after the chaos restarts it.
        gw = self.start("gateway", darwin("gateway", "--connect", self.ep, "--robot", "s1",
                                          "--listen", f"127.0.0.1:{free_tcp_port()}",
                                          *login("gw")),
                        "gateway:", "router")
        self.start("foxglove", darwin("foxglove", "--connect", self.ep, "--robot", "s2",
                                      "--listen", "127.0.0.1:0", *login("fox")),
                   "foxglove:", "router")
        self.start("ros2", darwin("ros2", "--connect", self.ep, "--robot", "s3", *login("ros")),
                   "ros2:", "router")
        for kind, robot, user, where in (("observer", "*", "obs", self.ep),
                                         ("counter", "s2", "obs", self.ep),
                                         ("driver", "s1", "op", self.ep),
                                         ("legacy", "s1", "op", gw.ready_rest.strip())):
            self.start(kind, child(kind, where, robot, user, self.pw(user)), '{"t"', "router")
        self.recording = self.directory / "s2.mcap"
        self.start("recorder", darwin("record", "-o", str(self.recording), "--connect", self.ep,
                                      "--robot", "s2", "--topics", "status", *login("rec")), "",
                   "router")
        self.record_from = self.count()

    @property
    def users(self) -> Path:
        return self.directory / "users.toml"

    def count(self) -> int:
        last = self.procs["counter"].last_json("count")
        return int(last["count"]) if last else 0

    # -- chaos -----------------------------------------------------------------------------
    def chaos(self, stop: threading.Event) -> None:
        kinds = ["adapter", "client", "router", "link"]
        adapters = ["gateway", "foxglove", "ros2"]
        clients = ["driver", "observer", "driver", "legacy"]  # the lease kill, most often
        n = 0
        while not stop.wait(self.period):
            kind = kinds[n % len(kinds)]
            if kind == "adapter":
                self.restart(adapters[(n // 4) % len(adapters)])
            elif kind == "client":
                self.kill_client(clients[(n // 4) % len(clients)])
            elif kind == "router":
                self.bounce_router()
            elif self.net is not None:
                self.bounce_link(cut=(n // 4) % 2 == 0)
            n += 1

    def kill_client(self, name: str) -> None:
        held = False
        if name == "driver":
            lease = (self.procs["observer"].last_json("lease") or {}).get("lease", {})
            held = lease.get("s1") == "soak-driver"
        killed = time.time()
        proc = self.procs[name]
        proc.kill()
        if held:
            # Started again only after the check: a new driver would take the lease again.
            self.lease_checks += 1
            free = self.procs["observer"].wait_json(
                lambda m: m.get("t", 0) > killed + 0.5
                and m.get("lease", {}).get("s1") != "soak-driver", LEASE_STOP_S)
            self.lease_missed += 0 if free else 1
        proc.start()
        if not proc.wait_ready(READY_S):
            self.stuck.append(f"{name} (not ready after a restart: {proc.tail()})")

    def bounce_router(self) -> None:
        self.procs["router"].kill()
        time.sleep(2.0)
        self.restart("router")
        back = time.time()
        seen = self.procs["observer"].wait_json(
            lambda m: m.get("t", 0) > back and set(ROBOTS) <= set(m.get("listed", [])), 120.0)
        self.unlisted.append((seen["t"] - back) if seen else float("inf"))

    def bounce_link(self, cut: bool) -> None:
        if cut:
            self.net.link_down("s3")
        else:
            self.net.impair("s3", loss_pct=30.0, delay_ms=100.0)
        time.sleep(self.period / 3)
        self.net.link_up("s3") if cut else self.net.clear("s3")

    # -- figures ---------------------------------------------------------------------------
    def usage(self) -> dict[str, dict[str, float]]:
        return {name: group_usage(p) for name, p in self.procs.items() if p.running()}

    def finish(self, start_usage: dict[str, dict[str, float]], hours: float) -> None:
        end_usage = self.usage()
        published = self.count() - self.record_from
        self.procs["recorder"].terminate(15.0)
        self.figures.update(
            lease_stops_checked=self.lease_checks, lease_stops_missed=self.lease_missed,
            router_restarts=len(self.unlisted),
            longest_unlisted_s=round(max(self.unlisted), 1) if self.unlisted else None,
            published=published, recorded=count_recorded(self.recording), record_window=2,
        )
        for name in sorted(self.procs):
            if not self.procs[name].terminate(15.0):
                self.stuck.append(f"{name} (did not end within 15 s of SIGTERM)")
        self.figures["stuck"] = len(self.stuck)
        self.figures["driver_bursts"] = sum(1 for m in self.procs["driver"].json if m.get("held"))
        self.figures["driver_errors"] = [m["error"] for m in self.procs["driver"].json
                                         if "error" in m][-3:]
        legacy = self.procs["legacy"].last_json("received")
        self.figures["legacy_received"] = legacy["received"] if legacy else 0
        self.figures["legacy_errors"] = [m["error"] for m in self.procs["legacy"].json
                                         if "error" in m][-3:]
        self.figures["stuck_detail"] = self.stuck
        growth = {}
        for name, start in start_usage.items():
            end = end_usage.get(name, start)
            growth[name] = {k: [start[k], end[k], round((end[k] - start[k]) / hours, 1)]
                            for k in start}
        self.figures["processes"] = growth  # each: [start, end, growth per hour]


def count_recorded(path: Path) -> int:
    from mcap.reader import make_reader

    with path.open("rb") as f:
        return sum(1 for _, channel, _ in make_reader(f).iter_messages()
                   if channel.topic.endswith("status"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--period", type=float, help="seconds between chaos events")
    parser.add_argument("--no-netns", action="store_true", help="no namespace for s3's link")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    period = args.period or max(15.0, min(60.0, args.minutes * 3.0))
    with ExitStack() as stack:
        directory = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="soak-")))
        net = None
        if not args.no_netns:
            from tests.fixtures.netns import network, unavailable

            if unavailable() is None:
                net = stack.enter_context(network(leaves=("s3",), impairable=("s3",)))
        soak = Soak(args.minutes, period, directory, net)
        stack.callback(lambda: [p.kill() for p in soak.procs.values()])
        signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
        began = time.monotonic()
        soak.setup()
        time.sleep(min(20.0, period))  # warm-up: imports done, sessions up
        start_usage = soak.usage()
        stop = threading.Event()
        chaos = threading.Thread(target=soak.chaos, args=(stop,), daemon=True)
        chaos.start()
        stop.wait(max(0.0, args.minutes * 60.0 - (time.monotonic() - began)))
        stop.set()
        chaos.join()
        soak.figures.update(minutes=round((time.monotonic() - began) / 60, 1), period_s=period,
                            netns=net is not None)
        soak.finish(start_usage, max(1e-3, (time.monotonic() - began) / 3600))
    if args.json:
        print(json.dumps(soak.figures, indent=1))
    else:
        for key, value in soak.figures.items():
            print(f"{key}: {value}")
    ok = soak.figures["lease_stops_missed"] == 0 and soak.figures["stuck"] == 0
    return 0 if ok else 1


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
