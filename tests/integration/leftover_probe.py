"""Run by tests/integration/test_leftovers.py in a pytest of its own, which it then stops (its
name has no ``test_`` prefix, so the suite does not collect it): a whole ``darwin up`` tree, a
plain child process and a temporary directory, held until that pytest is stopped."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

from tests.fixtures.system import start_system


def descendants(pid: int) -> list[int]:
    """``pid``'s children, theirs, and so on (from /proc)."""
    parent: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            parent[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    found, frontier = [], [pid]
    while frontier:
        kids = [p for p, pp in parent.items() if pp in frontier]
        found += kids
        frontier = kids
    return found


def test_hold_a_system_until_stopped() -> None:
    with start_system() as system, tempfile.TemporaryDirectory() as tmp:
        # Not a darwin process, and in pytest's own process group: only the mark finds it.
        child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(3600)"])
        try:
            pids = [system.process.pid, *descendants(system.process.pid), child.pid]
            info = {"pids": pids, "run": os.environ["DARWIN_TEST_RUN"], "tmp": tmp}
            print("probe-ready: " + json.dumps(info), flush=True)
            threading.Event().wait(3600)  # until test_leftovers stops this pytest
        finally:
            child.kill()
            child.wait()
