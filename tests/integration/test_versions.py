"""Versions on the wire: the daemon announces its package version and protocol in its status;
every client checks them through the one check (schemas/versions.py). A daemon made to announce
another protocol (``DARWIN_ANNOUNCE_PROTOCOL``) is refused with one line naming both versions;
a minor skew is a warning and everything works."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from schemas.errors import IncompatibleProtocolError
from schemas.versions import ENV_ANNOUNCE, PACKAGE_VERSION, PROTOCOL_VERSION, fmt
from tests.fixtures.system import RunningSystem, run_darwin, start_system

OURS = fmt(PROTOCOL_VERSION)


@pytest.fixture(scope="module")
def newer_daemon() -> Iterator[RunningSystem]:
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(ENV_ANNOUNCE, f"{PROTOCOL_VERSION[0] + 1}.0")
        with start_system(gateway=False) as system:
            yield system


def _target(system: RunningSystem) -> list[str]:
    return ["--connect", system.endpoint, "--robot", system.robot]


def test_the_robot_api_refuses_another_major_naming_both(newer_daemon: RunningSystem) -> None:
    theirs = f"{PROTOCOL_VERSION[0] + 1}.0"
    with newer_daemon.robot_client(name="old") as robot:
        with pytest.raises(IncompatibleProtocolError) as caught:
            robot.check_protocol(timeout=10)
        message = str(caught.value)
        assert f"speaks protocol {OURS}" in message and f"speaks {theirs}" in message
        assert "upgrade this client" in message and "\n" not in message
        with pytest.raises(IncompatibleProtocolError):
            robot.command("config")  # nothing is sent to a daemon we do not speak to


def test_programs_refuse_in_one_line(newer_daemon: RunningSystem, tmp_path: Path) -> None:
    gateway = run_darwin("gateway", *_target(newer_daemon), "--listen", "127.0.0.1:0")
    record = run_darwin("record", "-o", str(tmp_path / "x.mcap"), *_target(newer_daemon))
    for done, name in ((gateway, "gateway"), (record, "record")):
        assert done.returncode == 1, done.stdout + done.stderr
        last = done.stderr.strip().splitlines()[-1]
        assert last.startswith(f"darwin {name}: darwin") or last.startswith(f"darwin {name}:")
        assert "incompatible; upgrade this client" in last
    assert not (tmp_path / "x.mcap").exists()
    listed = run_darwin("list", "--connect", newer_daemon.endpoint, "--wait", "10")
    assert listed.returncode == 0, listed.stderr
    line = next(x for x in listed.stdout.splitlines() if x.startswith(newer_daemon.robot))
    assert "(incompatible:" in line


def test_a_minor_skew_warns_and_works(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ENV_ANNOUNCE, f"{PROTOCOL_VERSION[0]}.{PROTOCOL_VERSION[1] + 1}")
    with start_system(gateway=False) as system, system.robot_client(name="older") as robot:
        warning = robot.check_protocol(timeout=10)
        assert warning is not None and "upgrade this client" in warning
        status = robot.wait_for("status", fresh=False)
        assert status.version == PACKAGE_VERSION
        assert robot.command("config")["robot"] == system.robot
        tokens = robot.session.liveliness().get(f"{robot.keys.alive}/**", timeout=5)
        keys = [str(r.ok.key_expr) for r in tokens if r.ok is not None]
        minor = f"{PROTOCOL_VERSION[0]}.{PROTOCOL_VERSION[1] + 1}"
        assert set(keys) == {robot.keys.alive, robot.keys.alive_version(minor, PACKAGE_VERSION)}
        listed = run_darwin("list", "--connect", system.endpoint)
        assert f"protocol {PROTOCOL_VERSION[0]}.{PROTOCOL_VERSION[1] + 1}" in listed.stdout
