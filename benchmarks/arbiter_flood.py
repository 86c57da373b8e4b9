"""The motion loop under command floods, against a clean run in the same `darwin up`.

    .venv/bin/python benchmarks/arbiter_flood.py --seconds 5

One `darwin up` (wire-timed emulator), the robot walking in place; then one phase per flood,
each ``--seconds`` long: clean, 8 clients reading registers (no lease needed), 8 clients
sending cheap lease-free commands, 8 clients sending misspelt fields, one 16 MB payload every
0.5 s. For each: ticks per second (from the published tick numbers over wall time), p99 and
max period and overruns (from ``status.loop``), the commands answered by kind, and ticks/s as a
fraction of the clean phase.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import msgpack

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from schemas import SCHEMA_VERSION
from schemas.keys import Keys
from schemas.session import open_client
from tests.fixtures.system import start_system

READERS = 8


def payload(client: str, **fields: object) -> bytes:
    return msgpack.packb({"v": SCHEMA_VERSION, "client": client, **fields}, use_bin_type=True)


FLOODS: dict[str, tuple[str, dict[str, object]] | None] = {
    "clean": None,
    "register reads": ("registers", {"id": 19, "address": 36, "length": 2}),
    "cheap commands": ("lease", {"op": "status"}),
    "misspelt fields": ("walk", {"op": "stop", "X": 0.1}),
    "16 MB payloads": ("lease", {"op": "status", "name": "x" * (16 * 1024 * 1024)}),
}


def flood(session, key: str, data: bytes, stop: threading.Event, answers: Counter, pause: float):
    """One client sending ``data`` to ``key`` until ``stop``, counting the answers by kind."""
    while not stop.is_set():
        replies = list(session.get(key, payload=data, timeout=5.0))
        for r in replies:
            if r.ok is not None:
                answers["ok"] += 1
                continue
            try:
                d = msgpack.unpackb(r.err.payload.to_bytes())
            except ValueError:
                d = None
            answers[d.get("code", "?") if isinstance(d, dict) else "timeout"] += 1
        if not replies:
            answers["none"] += 1
        if pause:
            stop.wait(pause)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=5.0)
    args = ap.parse_args()
    with start_system(gateway=False) as system, system.robot_client(name="bench") as robot:
        robot.wait_for("joints", timeout=30)
        robot.acquire()
        robot.walk(x=0.0)
        keys = Keys(system.robot)
        session = open_client(system.endpoint)
        clean_rate = None
        print(f"{'flood':<16} {'ticks/s':>8} {'vs clean':>9} {'p99 ms':>7} {'max ms':>7} "
              f"{'overruns':>8}  answers")
        for name, spec in FLOODS.items():
            stop = threading.Event()
            answers: Counter[str] = Counter()
            threads = []
            if spec is not None:
                verb, fields = spec
                big = name.startswith("16 MB")
                threads = [
                    threading.Thread(
                        target=flood,
                        args=(session, keys.cmd(verb), payload(f"flood{i}", **fields), stop,
                              answers, 0.5 if big else 0.0),
                        daemon=True,
                    )
                    for i in range(1 if big else READERS)
                ]
            before = robot.wait_for("status").loop
            first = robot.wait_for("joints")
            t0 = time.monotonic()
            for t in threads:
                t.start()
            time.sleep(args.seconds)  # the measuring window
            last = robot.wait_for("joints")
            elapsed = time.monotonic() - t0
            stop.set()
            for t in threads:
                t.join(timeout=10)
            after = robot.wait_for("status").loop
            rate = (last.tick - first.tick) / elapsed
            clean_rate = clean_rate or rate
            print(f"{name:<16} {rate:8.1f} {rate / clean_rate:9.2f} "
                  f"{after['period_p99_ms']:7.1f} {after['period_max_ms']:7.1f} "
                  f"{after['overruns'] - before['overruns']:8d}  {dict(answers)}")
        robot.halt()
        session.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
