"""The emulator's FTDI delivery (``ftdi_latency_ms``): replies reach the pty in USB packets of
at most 62 bytes, and a partial packet only when the latency timer fires; the daemon's bulk
read takes them whole."""

from __future__ import annotations

import subprocess
import time
from collections.abc import Callable

import pytest

from robot_daemon.bus.dxl import DxlBus, ReplyBudget
from robot_daemon.bus.packet import status_packet
from robot_daemon.bus.port import BlockingPortHandler
from robot_daemon.bus.tables import CM730, CM730_ID, SERVO_IDS, sensor_blocks
from robot_daemon.emulator import Emulator
from robot_daemon.emulator.ftdi import USB_PACKET_BYTES, FtdiChip
from robot_daemon.emulator.settings import EmulatorSettings
from schemas.errors import ConfigError
from tests.fixtures.emulator import darwin_command

BYTE_S = 10e-6


def bulk_replies() -> list[tuple[float, bytes]]:
    """A tick's 21 replies as the wire delivers them: each one's last byte time, its bytes."""
    t, out = 0.001, []
    for dxl_id, _, length in sensor_blocks():
        packet = status_packet(dxl_id, 0, bytes(range(length)))
        t += len(packet) * BYTE_S
        out.append((t, packet))
    return out


def test_replies_leave_the_chip_in_usb_packets_and_the_rest_at_the_latency_timer() -> None:
    replies = bulk_replies()
    latency = 0.001
    chunks = FtdiChip(BYTE_S, latency).deliver(replies)
    stream = b"".join(p for _, p in replies)
    assert b"".join(c for _, c in chunks) == stream
    assert all(len(c) <= USB_PACKET_BYTES for _, c in chunks)
    full, last = chunks[:-1], chunks[-1]
    assert all(len(c) == USB_PACKET_BYTES for _, c in full)
    assert len(full) == len(stream) // USB_PACKET_BYTES
    # A full packet leaves when its last byte is in the chip; the partial one a latency timer
    # after its first byte (the wire delivered the stream back to back here).
    first_byte = replies[0][0] - (len(replies[0][1]) - 1) * BYTE_S
    for k, (t, _) in enumerate(full):
        assert t == pytest.approx(first_byte + ((k + 1) * USB_PACKET_BYTES - 1) * BYTE_S)
    assert last[0] == pytest.approx(first_byte + len(full) * USB_PACKET_BYTES * BYTE_S + latency)
    assert [t for t, _ in chunks] == sorted(t for t, _ in chunks)


def test_a_gap_longer_than_the_timer_flushes_what_the_chip_holds() -> None:
    ping = status_packet(1, 0)
    chunks = FtdiChip(BYTE_S, 0.001).deliver([(0.0, ping), (0.010, ping)])
    assert [c for _, c in chunks] == [ping, ping]
    assert chunks[0][0] == pytest.approx(0.001 - 5 * BYTE_S)


def test_the_latency_timer_is_checked() -> None:
    with pytest.raises(ConfigError, match="ftdi_latency_ms"):
        EmulatorSettings.from_dict({"ftdi_latency_ms": -1.0})


def test_on_the_pty_bytes_come_in_usb_packets_and_the_tail_after_the_timer(
    emulator_factory: Callable[..., Emulator],
) -> None:
    latency_ms = 40.0
    emu = emulator_factory(ftdi_latency_ms=latency_ms, wire_timing=True)
    writes: list[int] = []
    write = emu.link.write

    def counted(data: bytes) -> int:
        writes.append(len(data))
        return write(data)

    emu.link.write = counted  # type: ignore[method-assign]
    port = BlockingPortHandler(emu.port)
    port.open(1_000_000)
    try:
        # Waits wide enough for the timer: the behaviour under test is the delivery.
        bus = DxlBus(port, ReplyBudget(margin_ms=latency_ms * 5))
        bus.write(CM730_ID, CM730.DXL_POWER.reg.address, b"\x01")
        # A 6-byte status packet never fills a USB packet: it waits for the timer.
        sent = time.monotonic()
        assert bus.ping(SERVO_IDS[0])
        assert time.monotonic() - sent >= latency_ms / 1000
        writes.clear()
        result = bus.bulk_read(sensor_blocks())
        assert sorted(result.data) == sorted([*SERVO_IDS, CM730_ID])
        assert not result.missing and not result.corrupt
        assert writes and all(n <= USB_PACKET_BYTES for n in writes)
        total = sum(length + 6 for _, _, length in sensor_blocks())
        assert sum(writes) == total and len(writes) == -(-total // USB_PACKET_BYTES)
    finally:
        port.close()


def test_the_documented_command_serves_the_bus_reply_by_reply() -> None:
    """docs/loop-cpu.md: ``darwin sim --ftdi-latency-ms 0``."""
    proc = subprocess.Popen(
        darwin_command("sim", "--ftdi-latency-ms", "0"), stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout is not None
        port_name = next(line for line in proc.stdout if line.startswith("port:")).split()[1]
        port = BlockingPortHandler(port_name)
        port.open(1_000_000)
        try:
            bus = DxlBus(port, ReplyBudget(margin_ms=200.0))
            assert bus.ping(CM730_ID)
        finally:
            port.close()
    finally:
        proc.terminate()
        proc.wait(timeout=15)
        if proc.stdout:
            proc.stdout.close()
