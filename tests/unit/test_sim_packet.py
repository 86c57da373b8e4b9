"""The Protocol 1.0 codec: checksums, builders and the resynchronising parser (pure)."""

from __future__ import annotations

import pytest

from robot_daemon.bus.packet import (
    BadChecksum,
    Packet,
    PacketParser,
    checksum,
    instruction_packet,
    status_packet,
)


def test_packets_match_the_e_manual_examples() -> None:
    # e-manual: PING ID 1 is FF FF 01 02 01 FB; READ ID 1 address 0x2B length 1 ends in CC.
    assert instruction_packet(1, 0x01) == bytes.fromhex("FFFF010201FB")
    assert instruction_packet(1, 0x02, [0x2B, 0x01]) == bytes.fromhex("FFFF0104022B01CC")
    assert status_packet(1, 0, [0x20]) == bytes.fromhex("FFFF01030020DB")
    assert checksum([1, 2, 1]) == 0xFB


def test_builders_refuse_what_cannot_be_a_packet() -> None:
    with pytest.raises(ValueError, match="ID 255"):
        instruction_packet(255, 1)
    with pytest.raises(ValueError, match="do not fit"):
        instruction_packet(1, 3, bytes(250))


def test_parser_resynchronises_after_garbage_and_split_input() -> None:
    parser = PacketParser()
    ping = instruction_packet(3, 1)
    read = instruction_packet(4, 2, [36, 2])
    stream = b"\x00\x13\xff" + ping + b"\xfe\xff" + read
    frames = []
    for i in range(len(stream)):  # byte by byte: nothing depends on how reads split the input
        frames += parser.feed(stream[i : i + 1])
    assert frames == [Packet(3, 1, b""), Packet(4, 2, bytes([36, 2]))]
    assert parser.pending == 0
    assert parser.discarded == 5


def test_bad_checksum_is_reported_and_a_packet_inside_it_still_found() -> None:
    parser = PacketParser()
    bad = bytearray(instruction_packet(1, 3, [25, 1]))
    bad[-1] ^= 0xFF
    good = instruction_packet(2, 1)
    frames = parser.feed(bytes(bad) + good)
    assert frames[0] == BadChecksum(1, 3, bytes(bad))
    assert frames[-1] == Packet(2, 1, b"")


def test_a_truncated_packet_expires_and_releases_the_packet_behind_it() -> None:
    parser = PacketParser()
    # A header claiming 200 bytes swallows the valid PING that follows it...
    assert parser.feed(b"\xff\xff\x05\xc8\x03" + instruction_packet(7, 1)) == []
    assert parser.pending > 0
    # ...until the line has been quiet long enough: then the search restarts after that header.
    assert parser.expire() == [Packet(7, 1, b"")]
    assert parser.pending == 0


def test_impossible_headers_are_skipped() -> None:
    parser = PacketParser()
    # ID 0xFF and LEN 0/1 can never start a packet; FF FF FF is a header shifted by one.
    frames = parser.feed(b"\xff\xff\xff\x01\x02\x01\xfb" + b"\xff\xff\x02\x01\x00")
    assert frames == [Packet(1, 1, b"")]
