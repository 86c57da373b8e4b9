"""benchmarks/push_table.py's tries: one whose policy stream did not start (a slow start under
load, or a run the status poll missed) is tried again, a bounded number of times, each said in
a line, and then left out of its cell: never counted as a fall or a stand, never a crash."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import pytest

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "push_table.py"


def _bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("push_table", BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_try_whose_stream_did_not_start_is_tried_again_and_then_left_out(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    bench = _bench()
    outcomes: list[object] = []

    def fake_try(*_: object) -> bool | None:
        result = outcomes.pop(0)
        if isinstance(result, Exception):
            raise result
        return result  # type: ignore[return-value]

    monkeypatch.setattr(bench, "_try", fake_try)
    late = bench.NotStarted("after 15 s")

    # Not started once, then a fall: the fall is the try's result, the retry said.
    outcomes[:] = [late, True]
    assert bench.one_try(None, None, None, "p", 12.0) is True
    out = capsys.readouterr().out
    assert "the policy stream did not start (after 15 s); trying again (1 of 3)" in out

    # A start that found the robot fallen is not a try either; then it stood.
    outcomes[:] = [None, late, False]
    assert bench.one_try(None, None, None, "p", 12.0) is False
    capsys.readouterr()

    # Never started: left out (None), after STARTS attempts, and said so.
    outcomes[:] = [late] * bench.STARTS
    assert bench.one_try(None, None, None, "p", 12.0) is None
    out = capsys.readouterr().out
    assert out.count("the policy stream did not start") == bench.STARTS
    assert f"left out of the table ({bench.STARTS} of {bench.STARTS})" in out
    assert outcomes == []

    # Three starts that found it fallen are still an error (the robot cannot stand).
    outcomes[:] = [None, None, None]
    with pytest.raises(RuntimeError, match="fallen before the shove"):
        bench.one_try(None, None, None, "p", 12.0)
