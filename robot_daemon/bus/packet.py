"""Dynamixel Protocol 1.0 packets: checksum, builders and an incremental parser.

Instruction: ``FF FF ID LEN INST params… CHK``; status: ``FF FF ID LEN ERR data… CHK``;
LEN = len(params) + 2 and CHK = ~(ID + LEN + INST/ERR + params) & 0xFF.

The parser is what a device's receiver does with the byte stream, made robust for a simulated
bus: it looks for ``FF FF``, skips headers whose ID or LEN cannot be valid, and on a bad
checksum (or a packet left incomplete, see :meth:`PacketParser.expire`) it gives up only the
first header byte and searches again, so a valid packet hidden behind garbage is still found.
It does no I/O and is shared by the emulator and anyone who needs to frame raw bytes.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

HEADER = b"\xff\xff"
MAX_ID = 0xFE  # 254 is broadcast; 0xFF can never be an ID
MIN_LENGTH = 2  # instruction/error + checksum
# The SDK's TXPACKET_MAX_LEN/RXPACKET_MAX_LEN: the longest whole packet is 250 bytes.
MAX_PACKET_BYTES = 250
MAX_LENGTH = MAX_PACKET_BYTES - 4
# Bytes of a packet beside its parameters (or data): FF FF ID LEN INST/ERR … CHK.
PACKET_OVERHEAD = 6


def checksum(body: Iterable[int]) -> int:
    """Protocol 1.0 checksum of ID, LEN, INST/ERR and parameters."""
    return ~sum(body) & 0xFF


def _build(dxl_id: int, code: int, params: bytes | Iterable[int]) -> bytes:
    if type(params) is not bytes:
        params = bytes(params)
    n = len(params)
    if not 0 <= dxl_id <= MAX_ID:
        raise ValueError(f"Dynamixel ID {dxl_id} is outside 0..{MAX_ID}")
    if n > MAX_LENGTH - MIN_LENGTH:
        raise ValueError(f"{n} parameter bytes do not fit one packet (at most {MAX_LENGTH - 2})")
    body = bytes((dxl_id, n + 2, code & 0xFF)) + params
    return HEADER + body + bytes((checksum(body),))


def instruction_packet(dxl_id: int, instruction: int, params: bytes | Iterable[int] = b"") -> bytes:
    return _build(dxl_id, instruction, params)


def status_packet(dxl_id: int, error: int, params: bytes | Iterable[int] = b"") -> bytes:
    return _build(dxl_id, error, params)


@dataclass(frozen=True)
class Packet:
    """A well-formed packet: ``code`` is the instruction (or, for a status, the error byte)."""

    id: int
    code: int
    params: bytes

    @property
    def raw(self) -> bytes:
        return _build(self.id, self.code, self.params)


@dataclass(frozen=True)
class BadChecksum:
    """A complete frame whose checksum did not match: the firmware answers with error 0x10."""

    id: int
    code: int
    raw: bytes


Frame = Packet | BadChecksum


class PacketParser:
    """Turn a byte stream into packets, resynchronising on the next ``FF FF`` after garbage."""

    def __init__(self, max_length: int = MAX_LENGTH) -> None:
        self._buf = bytearray()
        self._max_length = max_length
        self.discarded = 0  # bytes thrown away as garbage (for statistics and tests)

    @property
    def pending(self) -> int:
        """Bytes held while waiting for the rest of a packet."""
        return len(self._buf)

    @property
    def pending_id(self) -> int | None:
        """The ID of the packet held half-received, if its header has arrived."""
        buf = self._buf
        return buf[2] if len(buf) >= 3 and buf[0] == 0xFF and buf[1] == 0xFF else None

    def feed(self, data: bytes) -> list[Frame]:
        self._buf += data
        return self._scan()

    def expire(self) -> list[Frame]:
        """The line went quiet in the middle of a packet: drop that header and search again.

        A device's receiver times out an incomplete packet; bytes after the abandoned header
        may still hold a complete packet (e.g. a valid one sent after a truncated one).
        """
        if not self._buf:
            return []
        self._drop(1)
        return self._scan()

    def reset(self) -> None:
        self.discarded += len(self._buf)
        self._buf.clear()

    def _drop(self, n: int) -> None:
        del self._buf[:n]
        self.discarded += n

    def _scan(self) -> list[Frame]:
        out: list[Frame] = []
        buf = self._buf
        while True:
            start = buf.find(HEADER)
            if start < 0:
                # Keep a trailing FF: it may be the first half of the next header.
                keep = 1 if buf.endswith(b"\xff") else 0
                self._drop(len(buf) - keep)
                return out
            if start:
                self._drop(start)
            if len(buf) < 4:
                return out
            dxl_id, length = buf[2], buf[3]
            if dxl_id > MAX_ID or not MIN_LENGTH <= length <= self._max_length:
                self._drop(1)
                continue
            total = length + 4
            if len(buf) < total:
                return out
            frame = bytes(buf[:total])
            if checksum(frame[2:-1]) == frame[-1]:
                out.append(Packet(dxl_id, frame[4], frame[5:-1]))
                del buf[:total]
            else:
                out.append(BadChecksum(dxl_id, frame[4], frame))
                self._drop(1)
