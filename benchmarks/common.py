"""Small helpers the benchmarks share (run them from the repository root's interpreter)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

CLK_TCK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    """CPU time (user + system) process ``pid`` has used so far, from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # utime + stime


def cpu_seconds_ns(pid: int) -> float:
    """CPU time process ``pid``'s live threads have used so far, to the nanosecond (the
    scheduler's count, /proc/PID/task/*/schedstat), where :func:`cpu_seconds` counts in clock
    ticks (10 ms): a change of a few ms in a start is seen. A thread that has ended is not
    counted (the programs of ``darwin up`` keep theirs while they start)."""
    return sum(
        int((task / "schedstat").read_text().split()[0])
        for task in Path(f"/proc/{pid}/task").iterdir()
    ) / 1e9


REPO = Path(__file__).resolve().parents[1]


def with_hot_path(tree: Path) -> str:
    """Give ``tree`` (another revision's sources, run with this interpreter) this tree's built
    extension if it has none and the same ``_hotpath.c`` (a ``git archive`` or fresh worktree
    has none built, and its daemon would run the Python hot path); says which hot path the
    tree's daemon runs."""
    if list((tree / "robot_daemon").glob("_hotpath*.so")):
        return "compiled"
    ours = sorted((REPO / "robot_daemon").glob("_hotpath*.so"))
    source = tree / "robot_daemon" / "_hotpath.c"
    if ours and source.exists() and source.read_bytes() == (
        REPO / "robot_daemon" / "_hotpath.c"
    ).read_bytes():
        shutil.copy2(ours[0], tree / "robot_daemon" / ours[0].name)
        return "compiled (this tree's build)"
    return "Python (no compiled hot path built in that tree)"
