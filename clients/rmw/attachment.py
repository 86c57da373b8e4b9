"""The 33-byte attachment rmw_zenoh puts on every sample, query and reply, and entity GIDs.

rmw_zenoh_cpp ``attachment_helpers.cpp`` serialises ``int64 sequence_number``, ``int64
source_timestamp`` (ns since the epoch) and ``std::array<uint8_t, 16> gid`` with zenoh-ext's
serializer: little-endian integers, the array prefixed by its length as a LEB128 varint (0x10).
The GID is XXH3-128 of the entity's liveliness token, low 64 bits then high 64 bits
(``liveliness_utils.cpp``, ``Entity::Entity``), both little-endian.
"""

from __future__ import annotations

import struct
import time
from dataclasses import dataclass

import xxhash

from schemas.errors import ProtocolError

GID_SIZE = 16
SIZE = 8 + 8 + 1 + GID_SIZE
_HEAD = struct.Struct("<qqB")


class AttachmentError(ProtocolError, ValueError):
    """An rmw_zenoh attachment (sequence number, stamp, GID) that does not decode."""


def gid_of(token: str) -> bytes:
    return xxhash.xxh3_128_intdigest(token.encode()).to_bytes(GID_SIZE, "little")


@dataclass(frozen=True)
class Attachment:
    """rmw_zenoh's attachment: a sequence number, a source timestamp and the sender's GID."""

    sequence: int
    timestamp_ns: int
    gid: bytes

    def encode(self) -> bytes:
        return _HEAD.pack(self.sequence, self.timestamp_ns, GID_SIZE) + self.gid

    @classmethod
    def decode(cls, raw: bytes | None) -> Attachment:
        if raw is None:
            raise AttachmentError("no attachment: rmw_zenoh samples carry a 33-byte attachment")
        if len(raw) != SIZE:
            raise AttachmentError(f"attachment is {len(raw)} bytes, rmw_zenoh's has {SIZE}")
        seq, ts, n = _HEAD.unpack_from(raw)
        if n != GID_SIZE:
            raise AttachmentError(f"attachment GID length byte is {n:#x}, expected 0x10")
        return cls(seq, ts, bytes(raw[_HEAD.size :]))


class Sequencer:
    """Sequence numbers from 1, one per put, for one publisher (or one service client)."""

    def __init__(self, gid: bytes) -> None:
        self.gid = gid
        self._next = 1

    def next(self, now_ns: int | None = None) -> bytes:
        seq = self._next
        self._next += 1
        return Attachment(seq, now_ns if now_ns is not None else time.time_ns(), self.gid).encode()
