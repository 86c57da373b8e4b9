"""A tolerant, low-level walk over an MCAP file's records: what ``read_recording()`` and
``darwin record recover`` read.

The stock readers stop at the first problem (a missing summary, a half-written chunk). This one
keeps every record that is whole and sound and says where and why it stopped or skipped:

* a **cut** (the file ends inside a record: a killed recorder) ends the walk; ``cut_at`` is the
  end of the last whole record, ``size`` the file's length;
* a **bad record** whose length fits the file (a chunk failing its CRC or decompression, a
  record that does not parse) is skipped and described in ``dropped``, with the message counts
  its message indexes list; a length that cannot be right is skipped by searching for the next
  chunk that checks out (``resync``).

Only data-section content is yielded (header, schemas, channels, messages, metadata,
attachments); indexes and the summary are rebuilt by whoever writes a new file.
"""

from __future__ import annotations

import mmap
import os
import struct
import zlib
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from io import BytesIO
from typing import Any

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    DataEnd,
    Footer,
    Header,
    Message,
    MessageIndex,
    Metadata,
    Schema,
)

from schemas.errors import RecordingError

MAGIC = b"\x89MCAP0\r\n"
RECORD_HEAD = 9  # opcode (1) + length (8)
_PARSE_ERRORS = (
    McapError,
    EOFError,
    ValueError,
    IndexError,
    UnicodeDecodeError,
    MemoryError,
    OverflowError,
    struct.error,
)
_READERS: dict[int, Any] = {
    Opcode.HEADER: Header.read,
    Opcode.FOOTER: Footer.read,
    Opcode.SCHEMA: Schema.read,
    Opcode.CHANNEL: Channel.read,
    Opcode.CHUNK: Chunk.read,
    Opcode.MESSAGE_INDEX: MessageIndex.read,
    Opcode.METADATA: Metadata.read,
    Opcode.ATTACHMENT: Attachment.read,
    Opcode.DATA_END: DataEnd.read,
}


_CONTENT = (Schema, Channel, Message, Metadata, Attachment)


class NotMcapError(RecordingError):
    """The file holds no MCAP data at all (empty, another format, cut inside the header)."""


def _name(opcode: int) -> str:
    try:
        return Opcode(opcode).name.title().replace("_", "")
    except ValueError:
        return f"record with opcode 0x{opcode:02x}"


@dataclass
class Dropped:
    """A record the scan could not use: where, what and why, and the messages it held."""

    offset: int
    what: str  # "Chunk of 18,311 bytes"
    why: str  # "CRC mismatch"
    messages: Counter[int] = field(default_factory=Counter)  # channel id → count, from indexes

    def describe(self, topics: dict[int, str]) -> str:
        text = f"{self.what} at byte {self.offset} ({self.why})"
        if self.messages:
            counts = self.messages.items()
            per = ", ".join(f"{topics.get(c, f'channel {c}')} {n}" for c, n in counts)
            text += f": {sum(self.messages.values())} messages ({per})"
        return text


@dataclass
class ScanReport:
    """What a scan of an MCAP file found: how far it is whole, and what it dropped."""

    path: str
    size: int = 0
    header: Header | None = None
    complete: bool = False  # ended with a footer and the closing magic
    data_end: bool = False  # the data section was closed (a DataEnd record)
    cut_at: int | None = None  # end of the last whole record when the file ends inside one
    cut_record: str = ""  # what the file ends inside
    last_good: str = ""  # the last whole record before the cut ("Chunk at byte N")
    dropped: list[Dropped] = field(default_factory=list)
    orphans: Counter[int] = field(default_factory=Counter)  # messages of undefined channels
    topics: dict[int, str] = field(default_factory=dict)  # channel id → topic

    @property
    def truncated(self) -> bool:
        return not self.complete

    @property
    def damaged(self) -> bool:
        return not self.complete or bool(self.dropped) or bool(self.orphans)

    def where(self) -> str:
        """Where the file stops being readable, in one phrase."""
        if self.complete:
            damage = ", with unreadable parts" if self.damaged else ""
            return f"is complete ({self.size} bytes{damage})"
        if self.cut_at is None:
            if not self.data_end:
                return f"ends at byte {self.size} between records, before its summary"
            return f"ends at byte {self.size} inside its summary (all data is readable)"
        cut = (
            f"is readable up to byte {self.cut_at} of {self.size}: it ends inside {self.cut_record}"
        )
        return cut + (f"; last good record: {self.last_good}" if self.last_good else "")

    def drops(self) -> list[str]:
        out = [d.describe(self.topics) for d in self.dropped]
        out += [
            f"{n} messages of channel {c}, whose definition was lost"
            for c, n in self.orphans.items()
        ]
        return out

    def notice(self) -> str:
        """One line: what is wrong with the file and the command that repairs it."""
        if not self.damaged:
            return ""
        fix = f"run `darwin record recover {self.path}`"
        drops = f"unreadable parts ({'; '.join(self.drops())})" if self.drops() else ""
        if self.truncated:
            at = self.size if self.cut_at is None else self.cut_at
            also = f" and has {drops}" if drops else ""
            return f"{self.path} is truncated at byte {at}{also}: {fix}"
        return f"{self.path} has {drops}: {fix}"


class RecordScanner:
    """``for record in RecordScanner(path): …``; then ``.report`` says how the walk went.

    Raises :class:`NotMcapError` (before yielding anything) when there is nothing to read.
    ``light``: walk record boundaries only, without opening chunks (a quick "is it whole?").
    """

    def __init__(self, path: str | os.PathLike[str], *, light: bool = False) -> None:
        self.path = os.fspath(path)
        self.light = light
        self.report = ScanReport(self.path)
        self._channels: dict[int, Channel] = {}
        self._last_drop: Dropped | None = None

    def __iter__(self) -> Iterator[Any]:
        with open(self.path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            self.report.size = size
            if size == 0:
                raise NotMcapError(f"{self.path} is empty")
            with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
                yield from self._walk(data, size)

    # -- the walk -------------------------------------------------------------------------------
    def _walk(self, data: mmap.mmap, size: int) -> Iterator[Any]:
        rep = self.report
        head = data[: len(MAGIC)]
        if head != MAGIC:
            if MAGIC.startswith(head):
                raise NotMcapError(f"{self.path} is cut inside the MCAP magic ({size} bytes)")
            raise NotMcapError(f"{self.path} is not an MCAP file (starts with {data[:8]!r})")
        pos = len(MAGIC)
        opcode, length, record = self._read(data, pos, size)
        if length < 0:
            raise NotMcapError(f"{self.path} is cut inside the MCAP header ({size} bytes)")
        if opcode != Opcode.HEADER or not isinstance(record, Header):
            why = record if isinstance(record, str) else f"opcode 0x{opcode:02x}"
            raise NotMcapError(f"{self.path} has no readable MCAP header ({why})")
        rep.header = record
        yield record
        last = ("Header", pos)
        pos += RECORD_HEAD + length
        while pos < size:
            opcode, length, record = self._read(data, pos, size)
            if length < 0:  # the record runs past the end of the file
                nxt = self._resync(data, pos + 1, size)
                if nxt is None:
                    rep.cut_at = pos
                    rep.cut_record = self._cut_what(data, opcode, pos, size)
                    rep.last_good = f"{last[0]} at byte {last[1]}"
                    return
                self._drop(
                    pos,
                    f"{nxt - pos} unreadable bytes",
                    "a record length past the end of the file; skipped to the next sound chunk",
                )
                pos = nxt
                continue
            if isinstance(record, str):  # whole, but unsound
                self._drop(pos, f"{_name(opcode)} of {length} bytes", record)
            else:
                yield from self._accept(opcode, record)
            if isinstance(record, Footer):
                rep.complete = data[pos + RECORD_HEAD + length : size] == MAGIC
                return
            last = (_name(opcode), pos)
            pos += RECORD_HEAD + length

    def _read(self, data: mmap.mmap, pos: int, size: int) -> tuple[int, int, Any]:
        """(opcode, length, record | reason string | None); length -1 when it does not fit."""
        if pos + RECORD_HEAD > size:
            return data[pos] if pos < size else -1, -1, None
        opcode = data[pos]
        length = int.from_bytes(data[pos + 1 : pos + RECORD_HEAD], "little")
        if pos + RECORD_HEAD + length > size:
            return opcode, -1, None
        reader = _READERS.get(opcode)
        if reader is None or (self.light and opcode in (Opcode.CHUNK, Opcode.MESSAGE_INDEX)):
            return opcode, length, None  # indexes, summary, extensions: not needed
        body = data[pos + RECORD_HEAD : pos + RECORD_HEAD + length]
        try:
            stream = ReadDataStream(BytesIO(body))
            record = reader(stream, length) if opcode == Opcode.MESSAGE else reader(stream)
            if isinstance(record, Chunk):
                record = self._open_chunk(record)
        except _PARSE_ERRORS as exc:
            return opcode, length, f"{type(exc).__name__}: {exc}".rstrip(": ")
        return opcode, length, record

    @staticmethod
    def _cut_what(data: mmap.mmap, opcode: int, pos: int, size: int) -> str:
        if pos + RECORD_HEAD > size:
            return f"a record header at byte {pos} ({size - pos} of {RECORD_HEAD} bytes on disk)"
        declared = int.from_bytes(data[pos + 1 : pos + RECORD_HEAD], "little")
        return (
            f"a {_name(opcode)} record at byte {pos} ({size - pos - RECORD_HEAD} of {declared} "
            "bytes on disk)"
        )

    def _open_chunk(self, chunk: Chunk) -> list[Any]:
        """The records inside a chunk, or raise when it is damaged."""
        if chunk.compression == "zstd":
            import zstandard

            try:
                # A damaged frame header could claim any size: trust it only if it agrees.
                declared = zstandard.frame_content_size(chunk.data)
                if declared not in (-1, chunk.uncompressed_size):
                    raise ValueError(
                        f"zstd frame of {declared} bytes, chunk says {chunk.uncompressed_size}"
                    )
                raw = zstandard.ZstdDecompressor().decompress(
                    chunk.data, max_output_size=chunk.uncompressed_size
                )
            except zstandard.ZstdError as exc:
                raise ValueError(f"zstd: {exc}") from exc
        elif chunk.compression == "lz4":
            try:
                import lz4.frame
            except ImportError as exc:
                raise ValueError("lz4-compressed chunk: install the lz4 package") from exc
            raw = lz4.frame.decompress(chunk.data)
        elif chunk.compression == "":
            raw = chunk.data
        else:
            raise ValueError(f"unknown compression {chunk.compression!r}")
        if len(raw) != chunk.uncompressed_size:
            raise ValueError(f"{len(raw)} bytes uncompressed, {chunk.uncompressed_size} declared")
        if chunk.uncompressed_crc and zlib.crc32(raw) != chunk.uncompressed_crc:
            raise ValueError("CRC mismatch")
        records: list[Any] = []
        pos = 0
        while pos < len(raw):
            if pos + RECORD_HEAD > len(raw):
                raise ValueError(f"a record header cut at byte {pos} of the chunk")
            opcode = raw[pos]
            length = int.from_bytes(raw[pos + 1 : pos + RECORD_HEAD], "little")
            end = pos + RECORD_HEAD + length
            if end > len(raw):
                raise ValueError(f"a record at byte {pos} runs past the end of the chunk")
            stream = ReadDataStream(BytesIO(raw[pos + RECORD_HEAD : end]))
            if opcode == Opcode.MESSAGE:
                records.append(Message.read(stream, length))
            elif opcode == Opcode.CHANNEL:
                records.append(Channel.read(stream))
            elif opcode == Opcode.SCHEMA:
                records.append(Schema.read(stream))
            pos = end
        return records

    def _accept(self, opcode: int, record: Any) -> Iterator[Any]:
        rep = self.report
        if isinstance(record, MessageIndex):
            # Indexes right after a dropped chunk say what it held.
            if self._last_drop is not None and self._last_drop.what.startswith("Chunk"):
                self._last_drop.messages[record.channel_id] += len(record.records)
            return
        self._last_drop = None
        if isinstance(record, DataEnd):
            rep.data_end = True
            return
        if rep.data_end or not isinstance(record, (list, *_CONTENT)):
            return  # the summary repeats schemas and channels: already seen
        for item in record if isinstance(record, list) else [record]:
            if isinstance(item, Channel):
                self._channels[item.id] = item
                rep.topics[item.id] = item.topic
            elif isinstance(item, Message) and item.channel_id not in self._channels:
                rep.orphans[item.channel_id] += 1
                continue
            yield item

    def _drop(self, pos: int, what: str, why: str) -> None:
        drop = Dropped(pos, what, why)
        self.report.dropped.append(drop)
        self._last_drop = drop

    def _resync(self, data: mmap.mmap, start: int, size: int) -> int | None:
        """The offset of the next chunk that checks out after ``start``, if any."""
        pos = start
        while True:
            pos = data.find(bytes([Opcode.CHUNK]), pos, size)
            if pos < 0:
                return None
            _, length, record = self._read(data, pos, size)
            if length >= 0 and isinstance(record, list):
                return pos
            pos += 1
