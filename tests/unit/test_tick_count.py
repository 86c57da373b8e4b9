"""The motion tick's cost, guarded by counting: callgrind's instruction count of the walking
tick (benchmarks/tick_count.py) may not grow more than a few per cent over the figure recorded
for this interpreter, and a tick raises no exception (an exception raised and caught costs the
tick thousands of instructions: docs/loop-cpu.md)."""

from __future__ import annotations

import contextlib
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

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


class ExceptionWatch:
    """Every exception raised during the ticks it watches, from both of the interpreter's hooks:
    the trace's 'exception' events (raised in, or passed through, a Python frame) and the
    profile's 'c_exception' events (a built-in function or method called from Python raised it,
    e.g. ``dict.pop`` of a missing key, whether the caller catches it or not)."""

    def __init__(self) -> None:
        self.raised: list[str] = []

    def _trace(self, frame, event, arg):  # type: ignore[no-untyped-def]
        if event == "exception":
            self.raised.append(f"raised {arg[0].__name__} at {frame.f_code.co_filename}:"
                               f"{frame.f_lineno} ({frame.f_code.co_name})")
        return self._trace

    def _profile(self, frame, event, arg):  # type: ignore[no-untyped-def]
        if event == "c_exception":
            self.raised.append(f"C call {getattr(arg, '__qualname__', arg)!s} raised at "
                               f"{frame.f_code.co_filename}:{frame.f_lineno}")

    def ticks(self, daemon: Any, n: int) -> list[str]:
        from tick_count import one_tick

        sys.settrace(self._trace)
        sys.setprofile(self._profile)
        try:
            for _ in range(n):
                one_tick(daemon)
        finally:
            sys.setprofile(None)
            sys.settrace(None)
        return self.raised


def _warm_daemon(walking: bool) -> Any:
    from tick_count import one_tick, tick_daemon

    daemon = tick_daemon(walking, seconds=1.0)
    for _ in range(20):
        one_tick(daemon)
    return daemon


@pytest.mark.parametrize("walking", [True, False], ids=["walking", "standing"])
def test_a_tick_raises_no_exception(walking: bool) -> None:
    """No exception is raised in a tick, caught or not, walking or standing, over 30 ticks
    with status due (every 12.5 ticks): each one raised and caught costs the tick thousands of
    instructions, and in the hot path it stands for a test that should be a condition."""
    assert ExceptionWatch().ticks(_warm_daemon(walking), 30) == []


def test_the_watch_sees_an_exception_raised_and_caught_in_a_tick() -> None:
    """The watch above can fail: an exception raised and caught inside the tick's frame (a
    Python ``raise``) and one from a C call (``int`` of a bad string), both caught where they
    are raised as a hot path would, are each reported."""
    daemon = _warm_daemon(True)
    frame = daemon.bus.frame

    def frame_with_caught_exceptions(*a: Any, **kw: Any) -> Any:
        try:
            raise KeyError("injected")
        except KeyError:
            pass
        with contextlib.suppress(ZeroDivisionError):
            divmod(1, 0)
        return frame(*a, **kw)

    daemon.bus.frame = frame_with_caught_exceptions
    raised = ExceptionWatch().ticks(daemon, 3)
    assert sum("raised KeyError" in r for r in raised) == 3, raised
    assert sum("C call divmod raised" in r for r in raised) == 3, raised
    assert sum("raised ZeroDivisionError" in r for r in raised) == 3, raised
