"""The emulator's FTDI delivery (robot_daemon/emulator/ftdi.py) against its definition taken
byte by byte: byte k of a reply whose last byte is on the wire at t arrives at t - (n-1-k) ×
byte time; a full 62-byte buffer goes at once, a partial one a latency after its first byte
(when the next byte would come later than that, or at the end).

The times are drawn from continuous ranges: a byte due exactly as the timer fires falls on one
side or the other by the floating point rounding of the sums (on the robot, by the chip's own
clock), so exact multiples would test the rounding, not the delivery."""

from __future__ import annotations

import random

import pytest

from robot_daemon.emulator.ftdi import USB_PACKET_BYTES, FtdiChip


def byte_by_byte(
    replies: list[tuple[float, bytes]], byte_s: float, latency_s: float, size: int
) -> list[tuple[float, bytes]]:
    out: list[tuple[float, bytes]] = []
    buf = bytearray()
    first = 0.0
    for t_end, packet in replies:
        n = len(packet)
        for k, byte in enumerate(packet):
            t = t_end - (n - 1 - k) * byte_s
            if buf and t > first + latency_s:
                out.append((first + latency_s, bytes(buf)))
                buf.clear()
            if not buf:
                first = t
            buf.append(byte)
            if len(buf) >= size:
                out.append((t, bytes(buf)))
                buf.clear()
    if buf:
        out.append((first + latency_s, bytes(buf)))
    return out


def bulk_read_like(rng: random.Random, byte_s: float) -> list[tuple[float, bytes]]:
    """Replies one after another on the wire, each after a return delay (sometimes none), of
    a servo's or the CM-730's length, now and then a long gap."""
    t = rng.uniform(0.0, 1.0)
    replies = []
    for _ in range(rng.randint(1, 30)):
        n = rng.choice((6, 8, 14, 36, rng.randint(1, 140)))
        gap = rng.choice((0.0, 0.0, rng.uniform(0, 2e-4), rng.uniform(0, 3e-2)))
        t += gap + n * byte_s
        replies.append((t, rng.randbytes(n)))
    return replies


@pytest.mark.parametrize("seed", range(4))
def test_delivery_is_the_byte_by_byte_definition(seed: int) -> None:
    rng = random.Random(seed)
    for _ in range(500):
        byte_s = rng.choice((rng.uniform(2e-6, 2e-4), 0.0))
        latency = rng.uniform(1e-5, 2e-2)
        size = rng.choice((USB_PACKET_BYTES, rng.randint(1, 80)))
        replies = bulk_read_like(rng, byte_s)
        got = FtdiChip(byte_s, latency, size).deliver(replies)
        want = byte_by_byte(replies, byte_s, latency, size)
        assert [data for _, data in got] == [data for _, data in want]
        assert [t for t, _ in got] == pytest.approx([t for t, _ in want], abs=1e-12)
        assert b"".join(data for _, data in got) == b"".join(p for _, p in replies)
