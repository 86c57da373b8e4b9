"""The client programs of ``benchmarks/soak.py``, each a process the chaos may kill; each prints
one JSON object per line on stdout (its first line ``{"ready": …}``), which the soak reads.

    python -m benchmarks.soak_children observer|driver|counter|legacy ENDPOINT ROBOT USER PWFILE
"""

from __future__ import annotations

import json
import sys
import threading
import time
from pathlib import Path

import zenoh

from schemas.keys import Keys, every_robot, robot_of
from schemas.messages import Status, decode
from schemas.session import Credentials, open_client


def say(**fields: object) -> None:
    print(json.dumps({"t": time.time(), **fields}), flush=True)


def observer(endpoint: str, _robot: str, creds: Credentials) -> None:
    """Like the TUI's fleet view: every second, which robots are live (their ``alive`` token,
    asked through the router) and who holds each lease (their status)."""
    from clients.fleet import live_robots

    session = open_client(endpoint, creds=creds)
    leases: dict[str, str | None] = {}

    def on_status(sample: zenoh.Sample) -> None:
        try:
            msg = decode(sample.payload.to_bytes(), Status)
            lease = msg.lease  # type: ignore[attr-defined]
            leases[robot_of(str(sample.key_expr))] = str(lease.get("name")) if lease else None
        except Exception:
            return

    session.declare_subscriber(every_robot().status, on_status)
    say(ready="observer")
    while True:
        try:
            listed = live_robots(session, timeout=1.0)
        except zenoh.ZError:
            listed = []
        say(listed=listed, lease=dict(leases))
        time.sleep(1.0)


def counter(endpoint: str, robot: str, creds: Credentials) -> None:
    """Counts ``robot``'s status publications (what the recorder should have), every second."""
    session = open_client(endpoint, creds=creds)
    count = [0]
    lock = threading.Lock()

    def on_status(_sample: zenoh.Sample) -> None:
        with lock:
            count[0] += 1

    session.declare_subscriber(Keys(robot).status, on_status)
    say(ready="counter")
    while True:
        time.sleep(0.5)
        with lock:
            say(count=count[0])


def driver(endpoint: str, robot: str, creds: Credentials) -> None:
    """Like a notebook: takes the lease, sends a burst of commands, lets go, again and again."""
    from clients.robot import Robot

    assert creds.user and creds.password
    say(ready="driver")
    while True:
        try:
            with Robot(endpoint, robot, user=creds.user, password=creds.password,
                       name="soak-driver") as r, r.control("soak-driver"):
                say(held=True)
                for i in range(25):
                    r.command("led", eye=[i % 32, 0, 0])
                    time.sleep(0.2)
            say(held=False)
        except Exception as exc:  # the router may be away: try again
            say(error=f"{type(exc).__name__}: {exc}"[:200])
        time.sleep(1.0)


def legacy(address: str, _robot: str, _creds: Credentials) -> None:
    """A legacy TCP client of the gateway: monitors the joints and counts what arrives."""
    from tests.legacy_client import LegacyClient

    host, _, port = address.rpartition(":")
    got = 0
    say(ready="legacy")
    while True:
        try:
            with LegacyClient(host, int(port), "big", False, timeout=10.0) as c:
                c.send({"monitor": {"motors": 1, "gyroscope": 1, "period": 100}})
                while c.recv() is not None:
                    c.received.clear()  # the test client keeps everything; a soak must not
                    got += 1
                    if got % 5 == 0:
                        say(received=got)
                say(error="the gateway closed the connection")
        except Exception as exc:
            say(error=f"{type(exc).__name__}: {exc}"[:200])
            time.sleep(1.0)


KINDS = {"observer": observer, "counter": counter, "driver": driver, "legacy": legacy}

if __name__ == "__main__":
    kind, where, robot, user, pw_file = sys.argv[1:6]
    password = Path(pw_file).read_text().strip()
    KINDS[kind](where, robot, Credentials(user, password))
