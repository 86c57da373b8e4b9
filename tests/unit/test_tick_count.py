"""The motion tick's cost, guarded by counting: callgrind's instruction count of the walking
tick (benchmarks/tick_count.py) may not grow more than a few per cent over the figure recorded
for this interpreter, and a tick raises no exception (an exception raised and caught costs the
tick thousands of instructions: docs/loop-cpu.md)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
def test_tick_instructions_within_recorded_figure() -> None:
    proc = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "tick_count.py"), "guard",
         "--ticks", "10", "--warm", "20"],
        capture_output=True, text=True, cwd=ROOT, timeout=900,
    )
    if proc.returncode == 2:
        pytest.skip(proc.stdout.strip())
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_a_tick_raises_no_exception() -> None:
    """Every exception raised in a Python frame during a walking tick with status due (the
    trace's 'exception' events): none."""
    from tick_count import one_tick, tick_daemon

    daemon = tick_daemon(True, seconds=1.0)
    for _ in range(20):
        one_tick(daemon)
    raised: list[str] = []

    def trace(frame, event, arg):  # type: ignore[no-untyped-def]
        if event == "exception":
            raised.append(f"{frame.f_code.co_filename}:{frame.f_lineno} {arg[0].__name__}")
        return trace

    sys.settrace(trace)
    try:
        for _ in range(30):  # status is due every 12.5 ticks
            one_tick(daemon)
    finally:
        sys.settrace(None)
    assert raised == []
