"""The doctor's checks as functions of their facts (what the daemon's bring-up may share)."""

from __future__ import annotations

import calendar

from config.robotis_offsets import NotImported
from robot_daemon.bus.chains import CHAINS, first_missing, hidden_behind
from robot_daemon.doctor import checks as C


def mx(i: int, firmware: int = 30) -> C.ServoInfo:
    return C.ServoInfo(i, "MX-28", firmware)


def test_the_five_chains_hold_every_servo_once() -> None:
    ids = [i for chain in CHAINS.values() for i in chain]
    assert sorted(ids) == list(range(1, 21))
    assert hidden_behind([9]) == {11, 13, 15, 17}
    assert hidden_behind([20]) == set()


def test_each_broken_branch_names_its_first_missing_id() -> None:
    found = {i: mx(i) for i in range(1, 21) if i not in (4, 6, 15, 17)}
    results = {c.name: c for c in C.servos(range(1, 21), found, 27)}
    assert results["servos"].status == C.FAIL
    assert results["chain left arm"].detail.startswith("ID 4 does not answer, nor the 1 behind")
    assert results["chain right leg"].detail.startswith("ID 15 does not answer")
    assert first_missing([17, 15]) == {"right leg": (15, (15, 17))}


def test_old_firmware_and_a_stranger_are_named() -> None:
    found = {i: mx(i) for i in range(1, 21)}
    found[3] = mx(3, firmware=26)
    found[8] = C.ServoInfo(8, "0x0136", 40)
    results = {c.name: c for c in C.servos(range(1, 21), found, 27)}
    assert "firmware 26 < 27" in results["servo 3"].detail
    assert "not an MX-28" in results["servo 8"].detail
    assert results["servos"].detail.startswith("18/20")


def test_the_daemon_may_hold_its_own_port() -> None:
    daemon = [
        C.Holder(42, "/usr/bin/python3 -m robot_daemon.launch.cli daemon --port /dev/ttyUSB0")
    ]
    assert C.port_holder_check("/dev/ttyUSB0", daemon, daemon_running=True).status == C.OK
    line = C.port_holder_check("/dev/ttyUSB0", daemon, daemon_running=False)
    assert line.status == C.FAIL and "kill 42" in line.fix
    demo = [C.Holder(7, "./demo")]
    assert C.port_holder_check("/dev/ttyUSB0", demo, daemon_running=True).status == C.FAIL


def test_thresholds() -> None:
    assert C.voltage(12.0, 11.1, 10.5).status == C.OK
    assert C.voltage(10.9, 11.1, 10.5).status == C.WARN
    assert C.voltage(10.0, 11.1, 10.5).status == C.FAIL
    assert C.temperatures({1: 40.0, 2: 65.0}, 60, 70).status == C.WARN
    assert C.loop_headroom({"tick_ms": 8.0, "work_p99_ms": 7.0}, 0.25).status == C.WARN
    assert C.loop_headroom({"tick_ms": 8.0, "work_p99_ms": 2.0}, 0.25).status == C.OK
    unset = calendar.timegm((2000, 1, 1, 0, 0, 0))
    assert C.clock(unset, 2024).status == C.FAIL
    now = calendar.timegm((2026, 1, 1, 0, 0, 0))
    assert C.clock(now, 2024, daemon_stamp=now + 30).status == C.WARN


def test_a_line_carries_its_fix_only_when_it_fails_or_warns() -> None:
    assert C.Check("a", C.FAIL, "bad", "do y").line() == "FAIL  a: bad — fix: do y"
    assert C.Check("a", C.OK, "fine", "do y").line() == "OK    a: fine"


def test_robotis_offsets_not_imported_is_a_warning_with_the_import_as_its_fix() -> None:
    missing = NotImported("/darwin/Data/config.ini calibrates 4 joint(s)", "import them")
    check = C.robotis_offsets("/darwin/Data/config.ini", missing)
    assert check.status == C.WARN and check.line().endswith("— fix: import them")
    assert C.robotis_offsets("/darwin/Data/config.ini", None).status == C.OK
