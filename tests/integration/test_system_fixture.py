"""The fixture that starts `darwin up` for the tests (tests/fixtures/system.py) starts it again
on other ports when one it chose was taken before the daemon listened, and only then."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from collections.abc import Iterator

import pytest

from schemas.session import free_tcp_port
from tests.fixtures import system as system_fixture
from tests.fixtures.leftovers import alive


@pytest.fixture
def taken() -> Iterator[int]:
    """A port something else listens on."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        yield int(s.getsockname()[1])


@pytest.fixture
def started(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The pids of every `darwin up` the fixture starts."""
    pids: list[int] = []
    spawn = system_fixture.spawn_darwin

    def spawn_and_note(*args: str, **kwargs: object) -> object:
        proc = spawn(*args, **kwargs)  # type: ignore[arg-type]
        pids.append(proc.pid)
        return proc

    monkeypatch.setattr(system_fixture, "spawn_darwin", spawn_and_note)
    return pids


def test_a_port_taken_before_the_daemon_listens_is_chosen_again(
    taken: int, started: list[int], monkeypatch: pytest.MonkeyPatch
) -> None:
    chosen = iter([taken])
    monkeypatch.setattr(system_fixture, "free_tcp_port", lambda: next(chosen, free_tcp_port()))
    with system_fixture.start_system(gateway=False) as running:
        assert not running.endpoint.endswith(f":{taken}")
        with running.robot_client(name="fixture test") as robot:
            robot.wait_for("joints", timeout=15)
    assert len(started) == 2  # the first stopped at start, saying the address was in use
    assert not any(map(alive, started))


def test_any_other_failure_at_start_is_not_tried_again(started: list[int]) -> None:
    bad_config = ["--config", "/nonexistent"]
    with (
        pytest.raises(RuntimeError, match="exited with"),
        system_fixture.start_system(gateway=False, extra_args=bad_config),
    ):
        pass
    assert len(started) == 1


SHARED_TESTS = '''
import json, os
from pathlib import Path

from tests.fixtures.leftovers import alive

OUT = Path(os.environ["SHARED_OUT"])


def note(**seen):
    with OUT.open("a") as f:
        f.write(json.dumps(seen) + "\\n")


def seen(test):
    return next(s for s in map(json.loads, OUT.read_text().splitlines()) if s["test"] == test)


def look(test, system):
    with system.robot_client(name=test) as robot:
        robot.wait_for("joints", timeout=15)
    note(test=test, pid=system.process.pid, robot=system.robot, endpoint=system.endpoint,
         object=id(system))


def test_a(robot_system):
    look("a", robot_system)


def test_b(robot_system):
    look("b", robot_system)


def test_c():
    note(test="c", a_alive=alive(seen("a")["pid"]))


def test_d(robot_system):
    look("d", robot_system)
'''


def test_the_shared_system_runs_only_while_its_tests_do(tmp_path) -> None:
    """``robot_system`` is one running system for consecutive tests, none while a test that
    does not use it runs, and the same object (same robot name, new processes) for a later
    one; nothing of it is left after the run."""
    (tmp_path / "test_shared.py").write_text(SHARED_TESTS)
    out = tmp_path / "seen.jsonl"
    env = dict(os.environ, SHARED_OUT=str(out), PYTHONPATH=str(system_fixture.REPO))
    env.pop("PYTEST_XDIST_WORKER", None)
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
         "-p", "tests.fixtures.system", "test_shared.py"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout + done.stderr
    seen = {s["test"]: s for s in map(json.loads, out.read_text().splitlines())}
    a, b, d = seen["a"], seen["b"], seen["d"]
    assert a["pid"] == b["pid"] and a["endpoint"] == b["endpoint"]
    assert seen["c"]["a_alive"] is False
    assert d["pid"] != a["pid"] and d["object"] == a["object"] and d["robot"] == a["robot"]
    assert not alive(a["pid"]) and not alive(d["pid"])
