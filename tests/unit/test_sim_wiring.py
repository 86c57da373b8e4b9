"""The emulator's wire: baud rate, broken chains and a factory-fresh servo, seen through the
stock dynamixel-sdk on a real pty."""

from __future__ import annotations

from collections.abc import Callable

import pytest
from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

from robot_daemon.bus.tables import MX28, SERVO_IDS
from robot_daemon.emulator import Emulator
from robot_daemon.emulator.control_service import handle_request
from tests.fixtures.emulator import open_sdk


def answering(port: PortHandler, ph: PacketHandler, ids=(*SERVO_IDS, 200)) -> set[int]:
    return {i for i in ids if ph.ping(port, i)[1] == COMM_SUCCESS}


def at_baud(port: PortHandler, bps: int) -> None:
    assert port.setBaudRate(bps)


def test_the_robots_servos_answer_only_at_1_mbps(emulator: Emulator) -> None:
    port, ph = open_sdk(emulator.port, emulator=emulator)
    try:
        assert answering(port, ph) == {*SERVO_IDS, 200}
        at_baud(port, 57_600)
        assert answering(port, ph, (1, 5, 200)) == set()
        at_baud(port, 1_000_000)
        assert answering(port, ph, (1, 5, 200)) == {1, 5, 200}
    finally:
        port.closePort()


def test_a_fresh_servo_answers_as_id_1_at_57600_only(
    emulator_factory: Callable[..., Emulator],
) -> None:
    emu = emulator_factory(fresh_servo=5)
    port, ph = open_sdk(emu.port, emulator=emu)
    try:
        assert answering(port, ph) == {*SERVO_IDS, 200} - {5}
        at_baud(port, 57_600)
        assert answering(port, ph, range(0, 21)) == {1}
        baud, result, _ = ph.read1ByteTxRx(port, 1, MX28.BAUD_RATE.reg.address)
        delay, _, _ = ph.read1ByteTxRx(port, 1, MX28.RETURN_DELAY_TIME.reg.address)
        assert result == COMM_SUCCESS and (baud, delay) == (34, 250)
        # Given 1 Mbps it leaves the 57,600 line and joins the robot's.
        # (the status of an ID write comes from the new ID, which the SDK does not wait for)
        frames = emu.stats["frames"]
        ph.write1ByteTxOnly(port, 1, MX28.ID.reg.address, 5)
        assert emu.wait_stat("frames", frames + 1)
        assert answering(port, ph, (1, 5)) == {5}
        frames = emu.stats["frames"]
        ph.write1ByteTxOnly(port, 5, MX28.BAUD_RATE.reg.address, 1)
        assert emu.wait_stat("frames", frames + 1)
        assert answering(port, ph, (1, 5)) == set()
        at_baud(port, 1_000_000)
        assert answering(port, ph) == {*SERVO_IDS, 200}
    finally:
        port.closePort()


def test_a_broken_cable_hides_every_servo_behind_it_on_its_branch(
    emulator_factory: Callable[..., Emulator],
) -> None:
    emu = emulator_factory(broken_after=[11])
    port, ph = open_sdk(emu.port, emulator=emu)
    try:
        assert answering(port, ph) == {*SERVO_IDS, 200} - {13, 15, 17}
        ok, _ = handle_request(emu, {"op": "chain", "broken_after": [3, 19]})
        assert ok
        assert answering(port, ph) == {*SERVO_IDS, 200} - {5, 20}
        ok, _ = handle_request(emu, {"op": "clear_faults"})
        assert ok and answering(port, ph) == {*SERVO_IDS, 200}
    finally:
        port.closePort()


def test_the_control_op_makes_a_servo_fresh_and_restore_keeps_it_so(emulator: Emulator) -> None:
    ok, _ = handle_request(emulator, {"op": "fresh_servo", "id": 7})
    assert ok
    handle_request(emulator, {"op": "restore"})
    port, ph = open_sdk(emulator.port, emulator=emulator)
    try:
        assert 7 not in answering(port, ph)
        at_baud(port, 57_600)
        assert answering(port, ph, (1, 7)) == {1}
    finally:
        port.closePort()


@pytest.mark.parametrize(
    ("request_", "words"),
    [
        ({"op": "chain", "broken_after": [42]}, "on no chain"),
        ({"op": "fresh_servo", "id": 99}, "no servo"),
    ],
)
def test_bad_wiring_requests_are_refused_naming_the_id(
    emulator: Emulator, request_: dict, words: str
) -> None:
    ok, payload = handle_request(emulator, request_)
    assert not ok and words.encode() in payload
