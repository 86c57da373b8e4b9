"""The legacy wire format: a 4-byte size header, then a UTF-8 JSON body. Pure: no sockets.

The original report only says the header is "a 4 bytes integer that represents the total size of
the message", so each connection's convention is detected from its first message (see
``legacy-protocol.md``, Framing):

- the header is a binary big-endian or little-endian integer, or four ASCII decimal digits;
- the size counts the body only, or the header plus the body.

A binary reading is plausible only up to the configured maximum; among the plausible readings the
one whose body is a complete JSON value wins, ties going to the defaults (big-endian, body only).
Replies are framed in the convention the client used.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from schemas.errors import ErrorCode, ProtocolError

HEADER_SIZE = 4
DEFAULT_MAX_MESSAGE = 1 << 20  # bytes of body
ASCII_MAX = 9999  # what four decimal digits can say


class ByteOrder(StrEnum):
    BIG = "big"
    LITTLE = "little"
    ASCII = "ascii"


@dataclass(frozen=True)
class Convention:
    """How one connection frames its messages."""

    order: ByteOrder = ByteOrder.BIG
    counted: bool = False  # the size includes the 4 header bytes

    def __str__(self) -> str:
        size = "header counted" if self.counted else "body only"
        if self.order == ByteOrder.ASCII:
            return f"ASCII digits, {size}"
        return f"{self.order.value}-endian, {size}"


DEFAULT_CONVENTION = Convention()

# Detection preference: the defaults first, so a body that reads as JSON either way keeps them.
CANDIDATES: tuple[Convention, ...] = tuple(
    Convention(order, counted) for order in ByteOrder for counted in (False, True)
)


class FramingError(ProtocolError):
    """The byte stream cannot be framed: the connection must be closed after the error reply."""

    def __init__(self, code: ErrorCode, message: str) -> None:
        super().__init__(message)
        self.code = code
        self.message = message


@dataclass(frozen=True)
class Frame:
    body: bytes
    value: Any  # the parsed JSON value


def header_size(header: bytes, convention: Convention) -> int | None:
    """The body size a header announces in ``convention``; None when it cannot be read so."""
    if convention.order == ByteOrder.ASCII:
        if not all(0x30 <= b <= 0x39 for b in header):
            return None
        size = int(header.decode("ascii"))
    else:
        size = int.from_bytes(header, convention.order.value)
    if convention.counted:
        size -= HEADER_SIZE
    return size if size >= 0 else None


def encode_frame(
    value: Any, convention: Convention, max_message: int = DEFAULT_MAX_MESSAGE
) -> bytes:
    """Frame a JSON value in ``convention``; ``FramingError`` if it cannot be said in it."""
    body = json.dumps(value, separators=(",", ":"), ensure_ascii=False).encode("utf-8")
    return frame_body(body, convention, max_message)


def frame_body(
    body: bytes, convention: Convention, max_message: int = DEFAULT_MAX_MESSAGE
) -> bytes:
    if len(body) > max_message:
        raise FramingError(
            ErrorCode.OUT_OF_RANGE,
            f"message of {len(body)} bytes is above the maximum of {max_message} bytes",
        )
    size = len(body) + (HEADER_SIZE if convention.counted else 0)
    if convention.order == ByteOrder.ASCII:
        if size > ASCII_MAX:
            raise FramingError(
                ErrorCode.OUT_OF_RANGE,
                f"message of {len(body)} bytes does not fit a 4-digit ASCII header "
                f"(at most {ASCII_MAX}): use a binary header to receive it",
            )
        header = f"{size:04d}".encode("ascii")
    else:
        header = size.to_bytes(HEADER_SIZE, convention.order.value)
    return header + body


def parse_body(body: bytes) -> Any:
    """The JSON value of a body; ``FramingError`` naming what is wrong otherwise."""
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FramingError(
            ErrorCode.INVALID, f"message body is not valid UTF-8 (byte {exc.start}): {exc.reason}"
        ) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        snippet = text[:60] + ("…" if len(text) > 60 else "")
        raise FramingError(
            ErrorCode.INVALID,
            f"message body is not valid JSON ({exc.msg} at line {exc.lineno} column {exc.colno}): "
            f"{snippet!r}",
        ) from None


def _try_parse(body: bytes) -> tuple[bool, Any]:
    try:
        return True, parse_body(body)
    except FramingError:
        return False, None


class FrameDecoder:
    """Turns the bytes of one connection into frames; detects the convention on the first one.

    ``feed(data)`` returns the complete frames so far; it raises ``FramingError`` on input that
    cannot be framed (the caller answers the error and closes the connection).
    """

    def __init__(self, max_message: int = DEFAULT_MAX_MESSAGE) -> None:
        self.max_message = max_message
        self.convention: Convention | None = None
        self.error: FramingError | None = None  # set once the stream cannot be framed
        self._buf = bytearray()

    @property
    def buffered(self) -> int:
        return len(self._buf)

    def reply_convention(self) -> Convention:
        """How to frame a reply: the client's convention, the default before it is known."""
        return self.convention or DEFAULT_CONVENTION

    def feed(self, data: bytes) -> list[Frame]:
        """Frames completed by ``data``. When the stream breaks after some good frames, those
        are returned and the error is kept in ``error`` (raised by the next call)."""
        if self.error is not None:
            raise self.error
        self._buf += data
        frames: list[Frame] = []
        while True:
            try:
                frame = self._next()
            except FramingError as exc:
                self.error = exc
                if not frames:
                    raise
                return frames
            if frame is None:
                return frames
            frames.append(frame)

    def _next(self) -> Frame | None:
        if len(self._buf) < HEADER_SIZE:
            return None
        if self.convention is None:
            return self._detect()
        header = bytes(self._buf[:HEADER_SIZE])
        size = self._checked_size(header, self.convention)
        end = HEADER_SIZE + size
        if len(self._buf) < end:
            return None
        body = bytes(self._buf[HEADER_SIZE:end])
        del self._buf[:end]
        return Frame(body, parse_body(body))

    def _checked_size(self, header: bytes, convention: Convention) -> int:
        size = header_size(header, convention)
        if size is None:
            raise FramingError(
                ErrorCode.INVALID,
                f"header {header!r} is not a size in this connection's convention ({convention})",
            )
        if size > self.max_message:
            raise FramingError(
                ErrorCode.OUT_OF_RANGE,
                f"header announces {size} bytes, above the maximum message size of "
                f"{self.max_message} bytes",
            )
        if size == 0:
            raise FramingError(ErrorCode.INVALID, "header announces an empty message body")
        return size

    def _plausible(self, header: bytes) -> list[tuple[Convention, int]]:
        found = []
        for conv in CANDIDATES:
            size = header_size(header, conv)
            if size is not None and 0 < size <= self.max_message:
                found.append((conv, size))
        return found

    def _detect(self) -> Frame | None:
        header = bytes(self._buf[:HEADER_SIZE])
        plausible = self._plausible(header)
        if not plausible:
            raise FramingError(
                ErrorCode.INVALID,
                f"header {header!r} is not a message size in any supported convention "
                f"(4-byte big- or little-endian integer, or 4 ASCII digits) up to "
                f"{self.max_message} bytes",
            )
        pending = False
        for conv, size in plausible:  # preference order
            end = HEADER_SIZE + size
            if len(self._buf) < end:
                pending = True
                continue
            ok, value = _try_parse(bytes(self._buf[HEADER_SIZE:end]))
            if ok:
                self.convention = conv
                body = bytes(self._buf[HEADER_SIZE:end])
                del self._buf[:end]
                return Frame(body, value)
        if pending:
            return None
        # Every plausible reading is complete and none is JSON: report it as the default would.
        conv, size = plausible[0]
        parse_body(bytes(self._buf[HEADER_SIZE : HEADER_SIZE + size]))
        raise FramingError(ErrorCode.INVALID, f"first message fits no framing ({header!r})")
