"""The fixture that starts `darwin up` for the tests (tests/fixtures/system.py) starts it again
on other ports when one it chose was taken before the daemon listened, and only then."""

from __future__ import annotations

import socket
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
