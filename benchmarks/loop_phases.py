"""Where the motion thread's CPU goes: the thread CPU time (user + system) of each phase of the
daemon's tick (bulk read, frame, motion step, sync write, publishing), walking against the
emulator as ``benchmarks/loop_cpu.py`` runs it, averaged over the ticks after a warm-up.

    python benchmarks/loop_phases.py [--seconds 12] [--ftdi-latency-ms 0]

The daemon runs through this file (``--launch``), which wraps the phases with
``time.thread_time`` before handing over to ``robot_daemon.launch.cli``; the wrappers cost a little
themselves, so compare phases within a run, and whole-tick CPU with ``loop_benchmark.py``.
"""

from __future__ import annotations

import argparse
import json
import os
import runpy
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

WARMUP_TICKS = 300
DUMP_EVERY = 250
PHASES = [
    ("robot_daemon.bus.robot_bus", "RobotBus", "read_sensors"),
    ("robot_daemon.bus.robot_bus", "RobotBus", "frame"),
    ("robot_daemon.motion.manager", "MotionManager", "step"),
    ("robot_daemon.bus.robot_bus", "RobotBus", "write_targets"),
    ("robot_daemon.engine.daemon", "Daemon", "_publish"),
]


def launch(out: str, argv: list[str]) -> None:
    """In the daemon's process: wrap the phases, then run the daemon's CLI."""
    import importlib

    acc: dict[str, float] = {}
    clock = time.thread_time

    def wrap(cls: Any, name: str) -> None:
        inner = getattr(cls, name)

        def timed(*a: Any, **k: Any) -> Any:
            t = clock()
            try:
                return inner(*a, **k)
            finally:
                acc[name] = acc.get(name, 0.0) + clock() - t

        setattr(cls, name, timed)

    for module, cls_name, name in PHASES:
        wrap(getattr(importlib.import_module(module), cls_name), name)
    daemon_cls = importlib.import_module("robot_daemon.engine.daemon").Daemon
    one_tick = daemon_cls._one_tick
    ticks = [0]

    def tick(self: Any, start: float) -> float:
        t = clock()
        result = one_tick(self, start)
        acc["tick"] = acc.get("tick", 0.0) + clock() - t
        ticks[0] += 1
        if ticks[0] == WARMUP_TICKS:
            acc.clear()
        n = ticks[0] - WARMUP_TICKS
        if n > 0 and n % DUMP_EVERY == 0:
            Path(out).write_text(json.dumps({"ticks": n, **{k: v / n for k, v in acc.items()}}))
        return result

    daemon_cls._one_tick = tick
    sys.argv = ["robot_daemon.launch.cli", *argv]
    runpy.run_module("robot_daemon.launch.cli", run_name="__main__", alter_sys=True)


def main() -> None:
    from benchmarks import loop_cpu

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=12.0)
    parser.add_argument("--ftdi-latency-ms", type=float, default=0.0)
    args = parser.parse_args()
    fd, out = tempfile.mkstemp(suffix=".json")
    os.close(fd)
    real_popen = subprocess.Popen

    def popen(cmd: list[str], *a: Any, **k: Any) -> subprocess.Popen[str]:
        if "daemon" in cmd and "-m" in cmd:  # the daemon, not the emulator
            i = cmd.index("-m")
            cmd = [*cmd[:i], __file__, "--launch", out, *cmd[i + 2 :]]
        return real_popen(cmd, *a, **k)

    loop_cpu.subprocess.Popen = popen  # type: ignore[misc]
    try:
        with loop_cpu.emulator(args.ftdi_latency_ms) as port:
            run = loop_cpu.daemon_run(ROOT, port, args.seconds)
        phases = json.loads(Path(out).read_text())
    finally:
        loop_cpu.subprocess.Popen = real_popen  # type: ignore[misc]
        os.unlink(out)
    print(f"walking, {loop_cpu.machine_load()}")
    print(f"process CPU {run.cpu_ms_per_tick:.3f} ms/tick at {run.ticks_per_s:.1f} ticks/s")
    print(f"motion thread, µs a tick over {phases['ticks']} ticks:")
    whole = phases["tick"]
    for _, _, name in PHASES:
        print(f"  {name:14s} {phases[name] * 1e6:6.0f}  {100 * phases[name] / whole:4.0f} %")
    rest = whole - sum(phases[name] for _, _, name in PHASES)
    print(f"  {'rest of tick':14s} {rest * 1e6:6.0f}  {100 * rest / whole:4.0f} %")
    print(f"  {'whole tick':14s} {whole * 1e6:6.0f}")


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--launch":
        launch(sys.argv[2], sys.argv[3:])
    else:
        main()
