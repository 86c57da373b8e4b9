"""A test run leaves nothing behind however it ends (tests/fixtures/leftovers.py): a pytest that
holds a ``darwin up`` tree, a plain child and a temporary directory is stopped with Ctrl-C's
SIGINT, with SIGTERM and with SIGKILL (a CI time limit), and every process, its run directory
and the temporary directory are gone soon after."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.fixtures.emulator import wait_until
from tests.fixtures.leftovers import alive
from tests.fixtures.system import REPO

PROBE = "tests/integration/leftover_probe.py"


@pytest.mark.parametrize(
    "sig", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL], ids=lambda s: s.name
)
def test_a_stopped_run_leaves_no_process_and_no_temporary_file(sig: signal.Signals) -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}
    proc = subprocess.Popen(
        [sys.executable, "-m", "pytest", "-q", "-s", "-p", "no:cacheprovider", "-p", "no:xdist",
         PROBE],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=REPO, env=env,
    )  # fmt: skip
    assert proc.stdout is not None
    seen: list[str] = []
    try:
        for line in proc.stdout:
            seen.append(line)
            if line.startswith("probe-ready: "):
                break
        else:
            raise AssertionError("the probe never got ready:\n" + "".join(seen))
        info = json.loads(line.removeprefix("probe-ready: "))
        pids, run, tmp = info["pids"], Path(info["run"]), Path(info["tmp"])
        assert len(pids) >= 3, info  # darwin up, at least one child of it, the plain child
        assert tmp.is_relative_to(run), info  # tempfile lands in the run directory
        proc.send_signal(sig)
        try:
            proc.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            why = f"the probe did not end within 120 s of {sig.name}:\n{stuck(proc)}"
            raise AssertionError(why) from None
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    wait_until(
        lambda: not any(map(alive, pids)) and not run.exists(),
        timeout=60,
        what=f"after {sig.name}: processes {[p for p in pids if alive(p)]} gone, {run} removed",
    )


def stuck(proc: subprocess.Popen[str]) -> str:
    """What a probe that does not end is doing: every thread's stack (the probe dumps them on
    SIGUSR1) and the processes it still has."""
    kids = subprocess.run(
        ["ps", "-o", "pid,ppid,stat,wchan:20,args", "--ppid", str(proc.pid), "-p", str(proc.pid)],
        capture_output=True, text=True,
    ).stdout  # fmt: skip
    # Seen once at load 8: a probe still in its loop 120 s after SIGINT. Whether the signal is
    # pending, blocked, ignored or caught, in which thread, says where it went.
    masks = []
    for task in sorted(Path(f"/proc/{proc.pid}/task").glob("*")):
        with contextlib.suppress(OSError):
            lines = (task / "status").read_text().splitlines()
            masks.append(f"thread {task.name}: " + " ".join(
                line.replace("\t", "") for line in lines
                if line.startswith(("Name", "SigPnd", "ShdPnd", "SigBlk", "SigIgn", "SigCgt"))
            ))  # fmt: skip
    proc.send_signal(signal.SIGUSR1)
    try:
        out, _ = proc.communicate(timeout=10)
    except subprocess.TimeoutExpired as e:
        out = e.output if isinstance(e.output, str) else (e.output or b"").decode(errors="replace")
    return f"{kids}\n" + "\n".join(masks) + f"\n{out}"
