"""The legacy wire format: a 4-byte size header, then a UTF-8 JSON body. Pure: no sockets.

The original report only says the header is "a 4 bytes integer that represents the total size of
the message", so each connection's convention is detected from its first message (see
``legacy-protocol.md``, Framing):

- the header is a binary big-endian or little-endian integer, or four ASCII decimal digits;
- the size counts the body only, or the header plus the body.

A binary reading is plausible only up to the configured maximum; among the plausible readings the
one whose body is a complete JSON value wins, ties going to the defaults (big-endian, body only).
Replies are framed in the convention the client used.

A body that is valid JSON but nests deeper than ``max_depth`` or holds a number literal longer
than ``max_number_length`` is still a well-delimited frame: it comes out as a frame carrying a
:class:`MessageError` (answered, connection kept), never as Python's own ``RecursionError`` or
``ValueError``.
"""

from __future__ import annotations

import functools
import json
import re
import threading
from dataclasses import dataclass
from enum import StrEnum
from typing import Any, Literal

from gateway.messages import LegacyError, MessageError, Request, parse_message
from schemas.errors import ErrorCode

HEADER_SIZE = 4
DEFAULT_MAX_MESSAGE = 1 << 20  # bytes of body
ASCII_MAX = 9999  # what four decimal digits can say
# A legacy message nests 3 deep (orchestrate list of objects) and its numbers are short.
DEFAULT_MAX_DEPTH = 32
DEFAULT_MAX_NUMBER_LENGTH = 32
# Bounds on those settings: json's decoder recurses once per level (and Python stops it near
# 1000), and int() refuses literals above 4300 digits.
MAX_DEPTH_LIMIT = 256
MAX_NUMBER_LENGTH_LIMIT = 4300


class ByteOrder(StrEnum):
    BIG = "big"
    LITTLE = "little"
    ASCII = "ascii"

    @property
    def byteorder(self) -> Literal["big", "little"]:
        """``int.from_bytes``'s name for a binary order."""
        return "little" if self is ByteOrder.LITTLE else "big"


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


class FramingError(LegacyError):
    """The byte stream cannot be framed: the connection must be closed after the error reply."""


@dataclass(frozen=True)
class BodyLimits:
    """What a well-framed JSON body may hold."""

    max_depth: int = DEFAULT_MAX_DEPTH  # nested lists and objects
    max_number_length: int = DEFAULT_MAX_NUMBER_LENGTH  # characters of one number literal


@dataclass(frozen=True)
class Frame:
    """One framed JSON body of a legacy client, parsed (or refused by a limit)."""

    body: bytes
    value: Any  # the parsed JSON value (None when refused)
    error: MessageError | None = None  # a well-framed body refused by a limit


def parse_frame(frame: Frame) -> Request:
    """The typed request of a frame; ``MessageError`` when its body or message is refused."""
    if frame.error is not None:
        raise frame.error
    return parse_message(frame.value)


def header_size(header: bytes, convention: Convention) -> int | None:
    """The body size a header announces in ``convention``; None when it cannot be read so."""
    if convention.order == ByteOrder.ASCII:
        if not all(0x30 <= b <= 0x39 for b in header):
            return None
        size = int(header.decode("ascii"))
    else:
        size = int.from_bytes(header, convention.order.byteorder)
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
        header = size.to_bytes(HEADER_SIZE, convention.order.byteorder)
    return header + body


_CONTAINERS = (dict, list)


# The lengths of the number literals above the limit in the body this thread is parsing.
_parsing = threading.local()


@functools.lru_cache(maxsize=8)
def _decoder(limit: int) -> json.JSONDecoder:
    """A decoder for number literals up to ``limit`` characters, built once: ``json.loads``
    with hooks builds a decoder and its scanner for every body (half of a small body's parse)."""

    def number(parse: type) -> Any:
        def hook(literal: str) -> Any:
            if len(literal) > limit:
                _parsing.too_long.append(len(literal))
                return None  # parsing goes on, so an invalid body is still reported as such
            return parse(literal)

        return hook

    return json.JSONDecoder(parse_int=number(int), parse_float=number(float))


def _deeper_than(text: str, value: Any, limit: int) -> bool:
    # Brackets inside strings count too, so this bound only over-counts: most bodies stop here.
    if text.count("[") + text.count("{") <= limit:
        return False
    # Level by level (json gives exact dicts and lists): no recursion, C-speed comprehensions.
    level = [value] if type(value) in _CONTAINERS else []
    for _ in range(limit):
        level = [
            child
            for node in level
            for child in (node.values() if type(node) is dict else node)
            if type(child) in _CONTAINERS
        ]
        if not level:
            return False
    return True


# A string literal, or what is left of an unterminated one: every quote that starts a match
# ends it, so the scan is linear (a pattern that can fail would rescan from every later quote).
_STRING = re.compile(r'"(?:[^"\\]++|\\[\s\S]?)*+"?')
_JSON_SPACE = " \t\r\n"


def _may_balance(text: str) -> bool:
    """Whether ``text`` could be one JSON list or object: its brackets balance (strings aside)."""
    bare = _STRING.sub('""', text).strip(_JSON_SPACE)
    return (
        bare[:1] in ("[", "{")
        and bare[-1:] in ("]", "}")
        and bare.count("[") == bare.count("]")
        and bare.count("{") == bare.count("}")
    )


def parse_body(body: bytes, limits: BodyLimits = BodyLimits()) -> Any:
    """The JSON value of a body: ``FramingError`` when it is not UTF-8 JSON (the frame itself
    is wrong), ``MessageError`` when it is JSON beyond ``limits`` (the frame is fine)."""
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FramingError(
            ErrorCode.INVALID, f"message body is not valid UTF-8 (byte {exc.start}): {exc.reason}"
        ) from None
    too_long: list[int] = []
    _parsing.too_long = too_long
    try:
        if text.startswith("\ufeff"):  # json.loads's own test, which a decoder leaves out
            raise json.JSONDecodeError("Unexpected UTF-8 BOM (decode using utf-8-sig)", text, 0)
        value = _decoder(limits.max_number_length).decode(text)
    except json.JSONDecodeError as exc:
        snippet = text[:60] + ("…" if len(text) > 60 else "")
        raise FramingError(
            ErrorCode.INVALID,
            f"message body is not valid JSON ({exc.msg} at line {exc.lineno} column {exc.colno}): "
            f"{snippet!r}",
        ) from None
    except RecursionError:
        # Far deeper than any allowed limit (MAX_DEPTH_LIMIT): the decoder gave up before it
        # could tell whether the body is JSON at all. Brackets that cannot balance say it is not
        # (that also keeps a wrong reading of the first header from passing for deep JSON).
        if not _may_balance(text):
            raise FramingError(
                ErrorCode.INVALID,
                "message body is not valid JSON (its lists and objects are not closed)",
            ) from None
        too_deep = True
    else:
        too_deep = _deeper_than(text, value, limits.max_depth)
    if too_deep:
        raise MessageError(
            ErrorCode.OUT_OF_RANGE,
            f"message nests lists and objects deeper than {limits.max_depth} levels",
        )
    if too_long:
        raise MessageError(
            ErrorCode.OUT_OF_RANGE,
            f"message has a number of {max(too_long)} characters, above the maximum of "
            f"{limits.max_number_length}",
        )
    return value


class FrameDecoder:
    """Turns the bytes of one connection into frames; detects the convention on the first one.

    ``feed(data)`` returns the complete frames so far; it raises ``FramingError`` on input that
    cannot be framed (the caller answers the error and closes the connection). A header may
    announce at most ``max_message`` bytes, so no more than that is ever held for a message
    still incomplete.
    """

    def __init__(
        self, max_message: int = DEFAULT_MAX_MESSAGE, limits: BodyLimits = BodyLimits()
    ) -> None:
        self.max_message = max_message
        self.limits = limits
        self.convention: Convention | None = None
        self.error: FramingError | None = None  # set once the stream cannot be framed
        self._buf = bytearray()
        # Readings of the first message found complete and not JSON: while the others wait for
        # their bytes they are not parsed again (the buffer only grows until one is taken).
        self._not_json: set[Convention] = set()

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

    def _take(self, end: int) -> Frame:
        """The frame whose body ends at ``end``, removed from the buffer."""
        body = bytes(self._buf[HEADER_SIZE:end])
        del self._buf[:end]
        try:
            return Frame(body, parse_body(body, self.limits))
        except MessageError as exc:
            return Frame(body, None, exc)

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
        return self._take(end)

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

    def _is_json(self, conv: Convention, end: int) -> bool:
        """Whether the first message read in ``conv`` is JSON (a body beyond the limits is)."""
        if conv in self._not_json:
            return False
        try:
            parse_body(bytes(self._buf[HEADER_SIZE:end]), self.limits)
        except FramingError:
            self._not_json.add(conv)
            return False
        except MessageError:
            pass
        return True

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
            elif self._is_json(conv, end):
                self.convention = conv
                return self._take(end)
        if pending:
            return None
        # Every plausible reading is complete and none is JSON: report it as the default would.
        conv, size = plausible[0]
        parse_body(bytes(self._buf[HEADER_SIZE : HEADER_SIZE + size]), self.limits)
        raise FramingError(ErrorCode.INVALID, f"first message fits no framing ({header!r})")
