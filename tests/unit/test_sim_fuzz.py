"""Property: whatever arrives on the line, the emulator keeps going and answers the next valid
packet correctly (pure bus + parser; the pty variant is in tests/integration/test_sim_fuzz.py)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_daemon.bus.packet import PacketParser, instruction_packet, status_packet
from robot_daemon.bus.tables import CM730_MODEL, Instruction
from robot_daemon.emulator.servo_chain import Bus

INSTRUCTIONS = [int(i) for i in Instruction] + [0x00, 0x07, 0x55, 0xFF]


@st.composite
def packets(draw: st.DrawFn) -> bytes:
    dxl_id = draw(st.sampled_from([1, 7, 20, 200, 254]) | st.integers(0, 253))
    inst = draw(st.sampled_from(INSTRUCTIONS))
    params = draw(st.binary(max_size=24))
    packet = bytearray(instruction_packet(dxl_id, inst, params))
    if draw(st.booleans()):  # corrupt: wrong checksum, a byte changed, or cut short
        how = draw(st.sampled_from(["checksum", "byte", "truncate"]))
        if how == "checksum":
            packet[-1] ^= draw(st.integers(1, 255))
        elif how == "byte":
            packet[draw(st.integers(2, len(packet) - 1))] = draw(st.integers(0, 255))
        else:
            del packet[draw(st.integers(1, len(packet) - 1)) :]
    return bytes(packet)


line_noise = st.lists(st.binary(min_size=1, max_size=40) | packets(), max_size=12)


def feed(bus: Bus, parser: PacketParser, data: bytes) -> list[bytes]:
    return [r.packet for frame in parser.feed(data) for r in bus.handle(frame)]


def settle(bus: Bus, parser: PacketParser) -> None:
    """What the emulator does when the line goes quiet: abandon partial packets."""
    for _ in range(300):
        if not parser.pending:
            return
        for frame in parser.expire():
            bus.handle(frame)
    raise AssertionError(f"the parser still holds {parser.pending} bytes")


def check_cm730_answers(bus: Bus, parser: PacketParser) -> None:
    cm = bus.cm730.id
    assert feed(bus, parser, instruction_packet(cm, Instruction.PING)) == [
        status_packet(cm, bus.cm730.alarm_bits())
    ]
    replies = feed(bus, parser, instruction_packet(cm, Instruction.READ, [0, 2]))
    if bus.cm730.status_return_level >= 1:
        assert replies == [status_packet(cm, 0, CM730_MODEL.to_bytes(2, "little"))]


@settings(max_examples=100, deadline=None)
@given(chunks=line_noise, seed=st.integers(0, 2**16))
def test_the_bus_survives_any_input_and_answers_the_next_valid_packet(
    chunks: list[bytes], seed: int
) -> None:
    bus = Bus(np.random.default_rng(seed), power_on_delay_s=0.0)
    parser = PacketParser()
    for chunk in chunks:
        for packet in feed(bus, parser, chunk):
            assert packet[:2] == b"\xff\xff"  # whatever it answers is a well-formed status
            assert PacketParser().feed(packet)[0].raw == packet
        bus.step(0.008)
    settle(bus, parser)
    check_cm730_answers(bus, parser)
