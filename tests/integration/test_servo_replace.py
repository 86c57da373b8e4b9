"""`darwin servo replace`: a factory-fresh MX-28 (ID 1 at 57,600 bps) takes a servo's place in
the emulator, end to end through the real command on the pty, and no other device's EEPROM
changes; every unsafe case is refused in one line with nothing written."""

from __future__ import annotations

import subprocess
from collections.abc import Callable

from robot_daemon.bus.tables import MX28, SERVO_IDS
from robot_daemon.emulator import Emulator
from tests.fixtures.emulator import open_sdk
from tests.fixtures.system import REPO, darwin_command

EEPROM_END = MX28.TORQUE_ENABLE.reg.address  # addresses 0..23


def eeproms(emu: Emulator) -> dict[str, bytes]:
    with emu.lock:
        out = {f"servo {i}": bytes(s.table.data[:EEPROM_END]) for i, s in emu.bus.servos.items()}
        out["cm730"] = bytes(emu.bus.cm730.table.data[:EEPROM_END])
    return out


def replace(emu: Emulator, *args: str, stdin: str = "") -> subprocess.CompletedProcess[str]:
    out = subprocess.run(
        darwin_command("servo", "replace", "--port", emu.port, "--scan-ids", "0-30", *args),
        input=stdin,
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
    )
    assert "Traceback" not in out.stderr, out.stderr
    return out


def refusal(out: subprocess.CompletedProcess[str]) -> str:
    assert out.returncode == 1, (out.stdout, out.stderr)
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("darwin servo:"), out.stderr
    return lines[0]


def test_a_fresh_servo_takes_its_place_and_nothing_else_changes(
    emulator_factory: Callable[..., Emulator],
) -> None:
    emu = emulator_factory(fresh_servo=5)
    before = eeproms(emu)
    out = replace(emu, "--id", "5", "--yes")
    assert out.returncode == 0, out.stderr
    assert "candidate: MX-28 firmware 30, ID 1 at 57600 bps" in out.stdout
    assert "servo 5: ID 5, 1000000 bps, return delay 0 µs, angle limits 0..4095 (read back)" in (
        out.stdout
    )
    after = eeproms(emu)
    changed = [k for k in before if before[k] != after[k]]
    assert changed == ["servo 5"]
    new = emu.bus.servo(5).table
    assert (new[MX28.ID], new[MX28.BAUD_RATE], new[MX28.RETURN_DELAY_TIME]) == (5, 1, 0)
    port, ph = open_sdk(emu.port, emulator=emu)
    try:
        assert all(ph.ping(port, i)[1] == 0 for i in SERVO_IDS)
    finally:
        port.closePort()


def test_typing_the_id_confirms_and_anything_else_writes_nothing(
    emulator_factory: Callable[..., Emulator],
) -> None:
    emu = emulator_factory(fresh_servo=12)
    before = eeproms(emu)
    line = refusal(replace(emu, "--id", "12", stdin="13\n"))
    assert "not confirmed" in line and "nothing written" in line
    assert eeproms(emu) == before
    out = replace(emu, "--id", "12", stdin="12\n")
    assert out.returncode == 0, out.stderr
    assert emu.bus.servo(12).table[MX28.ID] == 12


def test_an_id_that_answers_is_refused(emulator: Emulator) -> None:
    before = eeproms(emulator)
    assert "ID 5 already answers" in refusal(replace(emulator, "--id", "5", "--yes"))
    assert eeproms(emulator) == before


def test_two_candidates_are_refused(emulator_factory: Callable[..., Emulator]) -> None:
    emu = emulator_factory(fresh_servo=5)
    with emu.lock:
        emu.bus.factory_fresh(6, fresh_id=3)
    before = eeproms(emu)
    line = refusal(replace(emu, "--id", "5", "--yes"))
    assert "more than one candidate" in line and "ID 1 at 57600" in line and "ID 3 at 57600" in line
    assert eeproms(emu) == before


def test_old_firmware_is_refused(emulator_factory: Callable[..., Emulator]) -> None:
    emu = emulator_factory(fresh_servo=9)
    with emu.lock:
        emu.bus.servo(9).table[MX28.FIRMWARE_VERSION] = 26
    before = eeproms(emu)
    assert "firmware is 26 < 27" in refusal(replace(emu, "--id", "9", "--yes"))
    assert eeproms(emu) == before


def test_no_candidate_is_refused(emulator_factory: Callable[..., Emulator]) -> None:
    emu = emulator_factory(broken_after=[7])  # 9 and the rest of the right leg gone
    assert "no new servo answers" in refusal(replace(emu, "--id", "9", "--yes"))
