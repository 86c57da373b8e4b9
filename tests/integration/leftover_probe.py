"""Run by tests/integration/test_leftovers.py in a pytest of its own, which it then stops (its
name has no ``test_`` prefix, so the suite does not collect it): a whole ``darwin up`` tree, a
plain child process and a temporary directory, held until that pytest is stopped."""

from __future__ import annotations

import faulthandler
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tests.fixtures.system import start_system

# test_leftovers asks a probe that does not end for its threads' stacks.
faulthandler.register(signal.SIGUSR1, all_threads=True)
# The probe stands for a run in a terminal, where Ctrl-C raises KeyboardInterrupt. A suite
# started in the background of a shell without job control (`cmd &` in a script, a CI runner)
# inherits SIGINT ignored, and Python then leaves it ignored: the probe sat out the SIGINT for
# 120 s (its /proc SigIgn said so, 0x1001007: HUP, INT, QUIT, PIPE, XFSZ).
signal.signal(signal.SIGINT, signal.default_int_handler)


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
            # Until test_leftovers stops this pytest. In short sleeps: a signal the kernel hands
            # to another thread runs Python's handler only when the main thread next runs
            # bytecode, which one hour-long wait would put off for the hour.
            while True:
                time.sleep(0.5)
        finally:
            child.kill()
            child.wait()
