"""Bring-up on the bus (issue 25): the bulk read asks the CM-730 first, as every known
real-robot client does, and the emulator's chain makes a silent device mid-chain cost the ones
after it, as the real daisy chain does."""

from __future__ import annotations

from robot_daemon.bus.packet import BadChecksum
from robot_daemon.bus.tables import BROADCAST_ID, CM730_ID, Instruction
from robot_daemon.emulator import Emulator
from tests.unit.test_bus_robot import make_bus


def _bulk_reads(emulator: Emulator) -> list[list[int]]:
    """The device IDs of every bulk read the emulator took, in order."""
    emulator.wait_quiet()
    return [
        list(f.params[2::3])  # (0, then length, id, address per device)
        for f in list(emulator.received)
        if not isinstance(f, BadChecksum)
        and f.id == BROADCAST_ID
        and f.code == Instruction.BULK_READ
    ]


def _last_bulk_read_ids(emulator: Emulator) -> list[int]:
    return _bulk_reads(emulator)[-1]


def test_the_cm730_is_read_first_once_it_answers_and_last_while_it_is_silent(
    emulator: Emulator,
) -> None:
    emulator.bus.cm730_late_reads = 1000
    rb, _ = make_bus(emulator.port)
    try:
        rb.power_on()
        rb.scan()
        rb.initial_read()
        rb.read_sensors()
        ids = _last_bulk_read_ids(emulator)
        assert ids[-1] == CM730_ID and not rb.cm730_valid  # silent: it delays nobody
        assert all(rb.state.misses[j] == 0 for j in range(1, 21))  # every servo answered
        emulator.bus.cm730_late_reads = 0
        for _ in range(2):
            rb.read_sensors()
        assert _last_bulk_read_ids(emulator)[0] == CM730_ID
        assert rb.cm730_valid and rb.frame(1, 0.0, 0.008).imu_valid
    finally:
        rb.close()


def test_a_silent_servo_mid_chain_keeps_the_imu_valid_and_goes_offline(
    emulator: Emulator,
) -> None:
    rb, events = make_bus(emulator.port, reply_margin_ms=100.0)
    try:
        rb.power_on()
        rb.scan()
        rb.initial_read()
        emulator.api.silence(7)
        valid = 0
        for _ in range(rb.sensors.offline_after):
            emulator.received.clear()
            rb.read_sensors()
            first = _bulk_reads(emulator)[0]
            assert first[0] == CM730_ID and first.index(7) < len(first) - 1  # 7 mid-chain
            valid += rb.cm730_valid  # first in the chain: the servo after it cannot cost it
        assert valid == rb.sensors.offline_after
        assert not rb.state.online[7]
        assert [e[2]["id"] for e in events if e[0] == "servo_offline"] == [7]
    finally:
        rb.close()
