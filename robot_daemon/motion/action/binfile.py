"""The ROBOTIS action file (``motion_4096.bin``): 256 pages of 512 bytes, read and written
byte for byte.

Page layout (hardware.md): a 64-byte header — name (14 bytes, NUL padded) at 0, repeat 15,
schedule 16 (0 speed-based, 0x0A time-based), step count 20, speed 22, accel 24, next page 25,
exit page 26, checksum 31, per-joint slopes 32..62, a reserved byte at 63 — then 7 steps of
64 bytes: 31 little-endian uint16 positions indexed by joint id (bit 0x4000 = not driven),
pause at 62, time at 63. The 512 bytes of a valid page sum to 0xFF (mod 256).

Everything that is not one of those fields (reserved header bytes, steps after the step count,
the unused position slots 0 and 21..30) is kept as data so that a file read and written again
is identical; :data:`BLANK_PAGE` is what the stock tool writes for an empty page.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

from schemas.errors import DarwinError

PAGE_SIZE = 512
PAGE_COUNT = 256
FILE_SIZE = PAGE_SIZE * PAGE_COUNT
HEADER_SIZE = 64
STEP_SIZE = 64
MAX_STEPS = 7
SLOTS = 31  # position words per step, indexed by joint id (0 and 21..30 unused on this robot)
NAME_SIZE = 14
INVALID_BIT = 0x4000
NOT_DRIVEN = 0x4200  # what the stock tool writes for a joint a step does not drive
SCHEDULE_SPEED = 0x00
SCHEDULE_TIME = 0x0A

OFF_NAME, OFF_REPEAT, OFF_SCHEDULE, OFF_STEPS = 0, 15, 16, 20
OFF_SPEED, OFF_ACCEL, OFF_NEXT, OFF_EXIT, OFF_CHECKSUM = 22, 24, 25, 26, 31
OFF_SLOPES, SLOPES_SIZE = 32, 31
RESERVED_OFFSETS = (14, 17, 18, 19, 21, 23, 27, 28, 29, 30, 63)
DEFAULT_RESERVED = {63: 0x55}
DEFAULT_SLOPES = bytes([0x55] * 26 + [0] * 5)
DEFAULT_SPARE = (NOT_DRIVEN,) + (NOT_DRIVEN,) * 5 + (0,) * 5  # slot 0, then slots 21..30
SPARE_SLOTS = (0, *range(21, SLOTS))
JOINT_SLOTS = tuple(range(1, 21))


class MotionFileError(DarwinError):
    """A motion file or page that cannot be read or written: wrong size, bad field, unknown
    joint. ``field`` names the page-table field at fault (``name``, ``step[2].r_knee``…) when
    there is one."""

    def __init__(self, message: str, field: str | None = None) -> None:
        super().__init__(message)
        self.field = field


@dataclass
class Step:
    """One step of a motion page: 31 raw position words, then a pause and a time."""

    words: list[int] = field(default_factory=lambda: _blank_words())  # 31 raw position words
    pause: int = 0  # time units (8 ms at speed 32) to hold after reaching the step
    time: int = 0  # time units to reach the step (time-based schedule)

    def driven(self, joint_id: int) -> bool:
        return not self.words[joint_id] & INVALID_BIT

    def pack(self) -> bytes:
        return struct.pack("<31H", *self.words) + bytes([self.pause, self.time])

    @classmethod
    def unpack(cls, data: bytes) -> Step:
        return cls(list(struct.unpack("<31H", data[:62])), data[62], data[63])


def _blank_words() -> list[int]:
    words = [0] * SLOTS
    for slot, value in zip(SPARE_SLOTS, DEFAULT_SPARE, strict=True):
        words[slot] = value
    for slot in JOINT_SLOTS:
        words[slot] = NOT_DRIVEN
    return words


BLANK_STEP = Step()


@dataclass
class Page:
    """One page of a ROBOTIS ``motion.bin``: its header fields and steps."""

    number: int
    name: str = ""
    repeat: int = 1
    schedule: int = SCHEDULE_TIME
    speed: int = 32
    accel: int = 32
    next: int = 0
    exit: int = 0
    steps: list[Step] = field(default_factory=list)
    leftover: list[Step] = field(default_factory=list)  # stored steps after the step count
    slopes: bytes = DEFAULT_SLOPES
    reserved: dict[int, int] = field(default_factory=lambda: dict(DEFAULT_RESERVED))
    name_tail: bytes = b""  # bytes after the name's first NUL, when not all zero
    checksum: int | None = None  # stored checksum byte; None = compute it (sum rule)
    zero: bool = False  # an all-zero page (page 0 of the stock file)

    def pack(self) -> bytes:
        if self.zero:
            return bytes(PAGE_SIZE)
        buf = bytearray(PAGE_SIZE)
        name = self.name.encode("latin-1")
        if len(name) > NAME_SIZE:
            raise MotionFileError(
                f"page {self.number}: name {self.name!r} is longer than {NAME_SIZE} bytes", "name"
            )
        buf[0 : len(name)] = name
        if self.name_tail:
            start = len(name) + 1
            buf[start : start + len(self.name_tail)] = self.name_tail
        if not 0 <= len(self.steps) <= MAX_STEPS or len(self.steps) + len(self.leftover) > 7:
            raise MotionFileError(
                f"page {self.number} ({self.name}): {len(self.steps) + len(self.leftover)} "
                f"steps; a ROBOTIS .bin page holds at most {MAX_STEPS}",
                "step",
            )
        for off, value in (
            (OFF_REPEAT, self.repeat),
            (OFF_SCHEDULE, self.schedule),
            (OFF_STEPS, len(self.steps)),
            (OFF_SPEED, self.speed),
            (OFF_ACCEL, self.accel),
            (OFF_NEXT, self.next),
            (OFF_EXIT, self.exit),
            *self.reserved.items(),
        ):
            if not 0 <= value <= 255:
                raise MotionFileError(f"page {self.number}: byte {off} = {value} is not 0..255")
            buf[off] = value
        buf[OFF_SLOPES : OFF_SLOPES + SLOPES_SIZE] = self.slopes
        stored = self.steps + self.leftover
        for i in range(MAX_STEPS):
            step = stored[i] if i < len(stored) else BLANK_STEP
            off = HEADER_SIZE + i * STEP_SIZE
            buf[off : off + STEP_SIZE] = step.pack()
        buf[OFF_CHECKSUM] = 0
        buf[OFF_CHECKSUM] = self.checksum if self.checksum is not None else (0xFF - sum(buf)) & 0xFF
        return bytes(buf)

    @classmethod
    def unpack(cls, number: int, data: bytes) -> Page:
        if len(data) != PAGE_SIZE:
            raise MotionFileError(f"page {number}: {len(data)} bytes, expected {PAGE_SIZE}")
        if not any(data):
            return cls(number, zero=True)
        raw_name = data[:NAME_SIZE]
        name, _, tail = raw_name.partition(b"\0")
        count = data[OFF_STEPS]
        if count > MAX_STEPS:
            raise MotionFileError(f"page {number}: step count {count} is more than {MAX_STEPS}")
        steps = [
            Step.unpack(data[HEADER_SIZE + i * STEP_SIZE : HEADER_SIZE + (i + 1) * STEP_SIZE])
            for i in range(MAX_STEPS)
        ]
        leftover = steps[count:]
        while leftover and leftover[-1] == BLANK_STEP:
            leftover.pop()
        page = cls(
            number,
            name=name.decode("latin-1"),
            repeat=data[OFF_REPEAT],
            schedule=data[OFF_SCHEDULE],
            speed=data[OFF_SPEED],
            accel=data[OFF_ACCEL],
            next=data[OFF_NEXT],
            exit=data[OFF_EXIT],
            steps=steps[:count],
            leftover=leftover,
            slopes=bytes(data[OFF_SLOPES : OFF_SLOPES + SLOPES_SIZE]),
            reserved={off: data[off] for off in RESERVED_OFFSETS if data[off]},
            name_tail=tail.rstrip(b"\0") if any(tail) else b"",
        )
        if not checksum_ok(data):
            page.checksum = data[OFF_CHECKSUM]
        return page

    @property
    def blank(self) -> bool:
        """True for what the stock tool writes for an unused page."""
        if self.zero or self.steps or len(self.leftover) > MAX_STEPS:
            return False
        return self.pack() == _BLANK_BYTES


BLANK_PAGE = Page(0)
_BLANK_BYTES = BLANK_PAGE.pack()


def checksum_ok(page_bytes: bytes) -> bool:
    """The ROBOTIS rule: the 512 bytes of a valid page sum to 0xFF (mod 256)."""
    return sum(page_bytes) & 0xFF == 0xFF


def parse_bin(data: bytes, source: str = "motion file") -> list[Page]:
    """All 256 pages of an action file's bytes."""
    if len(data) != FILE_SIZE:
        raise MotionFileError(
            f"{source} is {len(data)} bytes; a ROBOTIS action file is exactly {FILE_SIZE} "
            f"({PAGE_COUNT} pages of {PAGE_SIZE})"
        )
    return [Page.unpack(n, data[n * PAGE_SIZE : (n + 1) * PAGE_SIZE]) for n in range(PAGE_COUNT)]


def read_bin(path: str | Path) -> list[Page]:
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise MotionFileError(f"cannot read motion file {p}: {exc.strerror}") from exc
    return parse_bin(data, str(p))


def build_bin(pages: list[Page] | dict[int, Page]) -> bytes:
    """The 131 072 bytes of an action file. Missing pages are blank (page 0: zeros). A page the
    format cannot hold raises :class:`MotionFileError` naming it."""
    by_number = pages if isinstance(pages, dict) else {p.number: p for p in pages}
    out = bytearray()
    for n in range(PAGE_COUNT):
        page = by_number.get(n)
        out += (bytes(PAGE_SIZE) if n == 0 else _BLANK_BYTES) if page is None else page.pack()
    return bytes(out)


def write_bin(path: str | Path, pages: list[Page] | dict[int, Page]) -> None:
    Path(path).write_bytes(build_bin(pages))
