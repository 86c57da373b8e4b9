"""`darwin up` start-up: how long until it serves, and what each of its processes costs.

Starts ``darwin up`` as the test fixture does (emulator with wire timing, daemon, gateway, no
camera, free loopback ports; :func:`tests.fixtures.system.start_system`) N times and measures,
from the spawn:

- wall time to the ``zenoh:`` line (a run without the gateway), to the ``gateway:`` line (the
  fixture's readiness) and to the first ``status`` a client receives;
- CPU time (user + system) of the start: the process tree's by the ``zenoh:`` line (``darwin
  up``, the daemon, the emulator) plus the gateway's by its line. On a loaded machine wall time
  mostly measures the others; CPU time is what this start costs whatever else runs;
- each program's CPU time (``up``, ``daemon``, ``sim``, ``gateway``, to the nanosecond:
  :func:`benchmarks.common.cpu_seconds_ns`) at the ``gateway:`` line, when ``darwin up`` has
  printed its addresses: which program a change made cheaper, by a few ms (``--per-program``
  measures only this, one start a run);
- in one extra run with ``PYTHONPROFILEIMPORTTIME``, the modules each process had imported by
  the first status (the ``[daemon]``/``[sim]``/``[gateway]`` prefixes of the relayed lines say
  whose).

Baselines, measured in the same run and interleaved with it: a bare interpreter (``python -c
pass``, the floor each of the four processes pays), and with ``--against REF`` (one or more) the
same measurements of another revision (``git archive REF``, run from a temporary directory with
this interpreter, with this tree's compiled hot path when its ``_hotpath.c`` is the same:
:func:`benchmarks.common.with_hot_path`), so before/after compare like for like, under the same
load. This tree runs in place and the others from their extracted copies (with PYTHONPATH): to
compare two revisions run alike, extract both (``--against main --against REF``; uncommitted
work: ``--against $(git stash create)`` after ``git add``).

Run by hand:  .venv/bin/python benchmarks/startup_benchmark.py [--runs 7] [--against main]
              [--per-program]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.common import cpu_seconds, cpu_seconds_ns, with_hot_path  # noqa: E402
from tests.fixtures.system import start_system  # noqa: E402

IMPORT_LINE = re.compile(r"^((?:\[[a-z0-9-]+\] )*)import time:\s+\d+ \|\s+\d+ \|")
KEYS = ("to_zenoh_line_s", "to_gateway_line_s", "to_first_status_s", "start_cpu_s")
PROGRAMS = ("up", "daemon", "sim", "gateway")
PROGRAM_KEYS = (*(f"{p}_cpu_s" for p in PROGRAMS), "sum_cpu_s")


def session_pids(session: int) -> list[int]:
    """Every live process of a session (``darwin up`` runs in its own: start_new_session)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if os.getsid(int(entry.name)) == session:
                    pids.append(int(entry.name))
            except OSError:
                continue  # gone meanwhile
    return pids


def command_of(pid: int) -> str:
    """The ``darwin`` subcommand process ``pid`` runs ("" if none)."""
    try:
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return ""
    words = [a.decode() for a in argv]
    if "robot_daemon.launch.cli" in words:
        rest = words[words.index("robot_daemon.launch.cli") + 1 :]
        return rest[0] if rest else ""
    return ""


def cpu_of(pids: list[int], count: Callable[[int], float] = cpu_seconds) -> float:
    total = 0.0
    for pid in pids:
        try:
            total += count(pid)
        except (OSError, IndexError, ValueError):
            continue
    return total


def bare_interpreter() -> tuple[float, float]:
    """Wall and CPU seconds of ``python -c pass`` (the floor of every child)."""
    before = os.times()
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", "pass"], check=True)
    wall = time.perf_counter() - start
    after = os.times()
    cpu = (after.children_user - before.children_user) + (
        after.children_system - before.children_system
    )
    return wall, cpu


def per_program(session: int) -> dict[str, float]:
    """CPU seconds so far of each program of a ``darwin up`` session, by its subcommand."""
    by: dict[str, list[int]] = {}
    for pid in session_pids(session):
        by.setdefault(command_of(pid), []).append(pid)
    cpu = {f"{name}_cpu_s": cpu_of(by.get(name, []), cpu_seconds_ns) for name in PROGRAMS}
    return {**cpu, "sum_cpu_s": sum(cpu.values())}


def one_start(source: Path) -> dict[str, float]:
    """One start without the gateway (to ``zenoh:``) and one with (to ``gateway:`` and the first
    status): seconds from spawn to each, the start's CPU seconds and each program's by the
    ``gateway:`` line."""
    start = time.perf_counter()
    with start_system(camera="none", gateway=False, timeout=120, source=source) as system:
        zenoh_s = time.perf_counter() - start  # start_system returns at the zenoh: line
        core_cpu = cpu_of(session_pids(system.process.pid))
    start = time.perf_counter()
    with start_system(camera="none", timeout=120, source=source) as system:
        gateway_s = time.perf_counter() - start  # … and with the gateway, at its line
        programs = per_program(system.process.pid)
        with system.robot_client(name="bench", timeout=30) as robot:
            robot.wait_for("status", timeout=60, fresh=False)
            status_s = time.perf_counter() - start
    return {
        "to_zenoh_line_s": zenoh_s,
        "to_gateway_line_s": gateway_s,
        "to_first_status_s": status_s,
        "start_cpu_s": core_cpu + programs["gateway_cpu_s"],
        **programs,
    }


def one_start_per_program(source: Path) -> dict[str, float]:
    """One start with the gateway: each program's CPU seconds by the ``gateway:`` line."""
    with start_system(camera="none", timeout=120, source=source) as system:
        return per_program(system.process.pid)


def modules_per_process(source: Path) -> dict[str, int]:
    """Modules each process of ``darwin up`` imported by the time it served a status."""
    os.environ["PYTHONPROFILEIMPORTTIME"] = "1"
    try:
        with start_system(camera="none", timeout=120, source=source) as system:
            with system.robot_client(name="bench", timeout=30) as robot:
                robot.wait_for("status", timeout=60, fresh=False)
            lines = list(system.lines)
    finally:
        del os.environ["PYTHONPROFILEIMPORTTIME"]
    counts: Counter[str] = Counter()
    for line in lines:
        m = IMPORT_LINE.match(line)
        if m:
            counts[m.group(1).strip() or "[up]"] += 1
    return dict(counts)


def extract(ref: str, into: Path) -> Path:
    """Revision ``ref`` of this repository, as files under ``into``."""
    into.mkdir()
    archive = subprocess.run(
        ["git", "archive", ref], cwd=REPO, capture_output=True, check=True
    ).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into


def medians(runs: list[dict[str, float]]) -> dict[str, float]:
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]}


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument(
        "--against",
        metavar="REF",
        action="append",
        default=[],
        help="also measure this git revision (again for more; ratios are to the first)",
    )
    parser.add_argument("--json", type=Path, help="also write the figures here")
    parser.add_argument(
        "--per-program",
        action="store_true",
        help="only each program's CPU at the gateway: line (one start a run, no import count)",
    )
    args = parser.parse_args()
    # As scripts/test runs the suite: bytecode and the parsed config kept after the first start.
    # Under PYTHONDONTWRITEBYTECODE (some shells set it) an extracted revision, which has no
    # cache, compiled every module at every start: main's four programs cost 2.06 s a start
    # that way and 1.40 s with their bytecode (two runs), and the comparison measured the
    # compiler.
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    measure = one_start_per_program if args.per_program else one_start
    with tempfile.TemporaryDirectory(prefix="startup-bench-") as tmp:
        trees: dict[str, Path] = {}
        for i, ref in enumerate(args.against):
            trees[ref] = extract(ref, Path(tmp) / str(i))
            print(f"{ref}: hot path {with_hot_path(trees[ref])}", flush=True)
        trees["this tree"] = REPO
        runs: dict[str, list[dict[str, float]]] = {name: [] for name in trees}
        bare: list[tuple[float, float]] = []
        for _ in range(args.runs):
            for name, source in trees.items():  # interleaved: both meet the same load
                bare.append(bare_interpreter())
                runs[name].append(measure(source))
        modules: dict[str, dict[str, int]] = {}
        if not args.per_program:
            modules = {name: modules_per_process(source) for name, source in trees.items()}
    bare_wall = statistics.median(b[0] for b in bare)
    bare_cpu = statistics.median(b[1] for b in bare)
    figures = {name: medians(r) for name, r in runs.items()}
    print(f"darwin up start-up, median of {args.runs} runs; baseline python -c pass, same run:")
    print(f"  bare interpreter: wall {bare_wall:.3f} s, CPU {bare_cpu:.3f} s")
    width = max(map(len, trees))
    tables = [(PROGRAM_KEYS, [f"{p} CPU" for p in PROGRAMS] + ["sum"])]
    if not args.per_program:
        labels = ["to `zenoh:`", "to `gateway:`", "to first status", "start CPU"]
        tables.insert(0, (KEYS, labels))
    for keys, labels in tables:
        print(f"  {'':<{width}}  " + "  ".join(f"{label:>17}" for label in labels))
        for name, fig in figures.items():
            bare_of = {k: bare_cpu if k.endswith("cpu_s") else bare_wall for k in keys}
            cells = [f"{fig[k]:6.3f} s ({fig[k] / bare_of[k]:4.0f}×)" for k in keys]
            print(f"  {name:<{width}}  " + "  ".join(f"{c:>17}" for c in cells))
        for name in list(figures)[1:] if args.against else []:
            before, after = figures[args.against[0]], figures[name]
            ratios = "  ".join(f"{after[k] / before[k]:17.2f}" for k in keys)
            print(f"  {'ratio':<{width}}  {ratios}   ({name} ÷ {args.against[0]})")
    print("  (×: in bare interpreters, wall or CPU; program CPU at the `gateway:` line)")
    for name, counts in modules.items():
        listed = ", ".join(f"{k} {v}" for k, v in counts.items())
        print(f"  modules imported by the first status, {name}: {listed}")
    if args.json:
        out = {
            "runs": args.runs,
            "bare_wall_s": bare_wall,
            "bare_cpu_s": bare_cpu,
            "figures": figures,
            "modules": modules,
        }
        args.json.write_text(json.dumps(out, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
