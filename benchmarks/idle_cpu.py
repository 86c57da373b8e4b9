"""What a simulated robot nobody drives costs: CPU seconds of each process of an idle
``darwin up`` (emulator, daemon, gateway), this tree against a baseline tree, side by side.

Most of the suite's tests start a simulated robot (:func:`tests.fixtures.system.start_system`:
the emulator with wire timing, the daemon, the gateway, no camera) and it costs CPU for as long
as it lives, whether the test drives it or not. Each round starts one ``darwin up`` from each
tree at the same time, waits until both serve a status and ``--settle`` seconds more, then
reads every process's CPU time (user + system, /proc) over the same ``--window`` seconds; the
trees start in turn first. Side by side, both meet the same load: on a shared machine only the
ratio in a round means much, and the median of the rounds' figures.

    .venv/bin/python benchmarks/idle_cpu.py                            # this tree only
    git worktree add /tmp/base main
    .venv/bin/python benchmarks/idle_cpu.py --baseline /tmp/base       # and the ratio

The baseline runs with this interpreter from its own sources (``PYTHONPATH``); its compiled hot
path (``robot_daemon/_hotpath*.so``) is this tree's when its ``_hotpath.c`` is the same (a fresh
worktree has none built, and the daemon would run its Python path). The emulator's share is
most of it; ``benchmarks/sim_count.py`` counts its answers in instructions.
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.common import with_hot_path  # noqa: E402
from benchmarks.startup_benchmark import command_of, cpu_of, session_pids  # noqa: E402
from tests.fixtures.system import RunningSystem, start_system  # noqa: E402

PROCESSES = ("sim", "daemon", "gateway")


def by_process(system: RunningSystem) -> dict[str, list[int]]:
    pids: dict[str, list[int]] = {name: [] for name in (*PROCESSES, "up")}
    for pid in session_pids(system.process.pid):
        pids.get(command_of(pid) or "up", pids["up"]).append(pid)
    return pids


def one_round(
    trees: dict[str, Path], order: list[str], settle: float, window: float
) -> tuple[dict[str, dict[str, float]], float]:
    """CPU seconds of each process of each tree over the same window, and the window's wall."""
    with contextlib.ExitStack() as stack:
        systems = {
            name: stack.enter_context(start_system(camera="none", timeout=120, source=trees[name]))
            for name in order
        }
        for system in systems.values():
            with system.robot_client(name="idle-bench", timeout=30) as robot:
                robot.wait_for("status", timeout=60, fresh=False)
        time.sleep(settle)  # bring-up's own work (power-on, first reads) is done
        pids = {name: by_process(system) for name, system in systems.items()}
        before = {n: {p: cpu_of(ids) for p, ids in procs.items()} for n, procs in pids.items()}
        start = time.monotonic()
        time.sleep(window)
        after = {n: {p: cpu_of(ids) for p, ids in procs.items()} for n, procs in pids.items()}
        wall = time.monotonic() - start
        for name, system in systems.items():
            if not system.alive:
                raise SystemExit(f"idle_cpu: {name}'s darwin up died:\n{system.output()}")
    cpu = {n: {p: after[n][p] - before[n][p] for p in after[n]} for n in after}
    return cpu, wall


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--baseline", type=Path, help="another source tree, measured beside")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--window", type=float, default=30.0, help="seconds measured a round")
    parser.add_argument("--settle", type=float, default=5.0, help="seconds after the status")
    args = parser.parse_args()
    trees = {"this tree": REPO}
    if args.baseline is not None:
        base = args.baseline.resolve()
        print(f"baseline {base}: hot path {with_hot_path(base)}", flush=True)
        trees = {"baseline": base, **trees}
    shares: dict[str, dict[str, list[float]]] = {n: {} for n in trees}
    names = list(trees)
    for k in range(args.rounds):
        order = names[k % len(names) :] + names[: k % len(names)]
        cpu, wall = one_round(trees, order, args.settle, args.window)
        line = []
        for name in names:
            figures = {p: 100 * s / wall for p, s in cpu[name].items()}
            figures["total"] = sum(figures.values())
            for p, share in figures.items():
                shares[name].setdefault(p, []).append(share)
            line.append(f"{name} {figures['total']:.1f} %")
        print(f"round {k + 1}: " + ", ".join(line), flush=True)
    rows = [*PROCESSES, "up", "total"]
    print(f"% of one core, median of {args.rounds} rounds of {args.window:g} s, side by side:")
    print(f"  {'':<10}" + "".join(f"{r:>9}" for r in rows))
    for name in names:
        print(
            f"  {name:<10}"
            + "".join(f"{statistics.median(shares[name][r]):9.2f}" for r in rows)
        )
    if args.baseline is not None:
        ratios = []
        for r in rows:
            base_share = statistics.median(shares["baseline"][r])
            now = statistics.median(shares["this tree"][r])
            ratios.append(f"{now / base_share:9.2f}" if base_share else f"{'-':>9}")
        print(f"  {'ratio':<10}" + "".join(ratios) + "   (this tree ÷ baseline)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
