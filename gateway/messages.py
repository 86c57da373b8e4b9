"""Legacy messages from clients: parsed and checked into typed requests. Pure: no I/O.

Every message is a JSON object with exactly one tag (``monitor``, ``operate``, ``led``,
``orchestrate``, ``walk``, ``playball``); see ``legacy-protocol.md``. Anything else raises
:class:`MessageError` with the spec's error code and a message naming the tag, field and value.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from schemas.errors import ErrorCode, ProtocolError

STREAMS = ("accelerometer", "camera", "gyroscope", "motors")
# Extension: a client may choose its own monitoring period (ms); unknown to old clients.
PERIOD_FIELD = "period"
PERIOD_MS_RANGE = (10, 10_000)
JOINT_IDS = range(1, 21)
POSITION_DEG_RANGE = (-360.0, 360.0)
LED_TARGETS = {26: "head", 27: "eye"}  # decision: 26 = forehead, 27 = eyes
MAX_ORCHESTRATE_ITEMS = 100
TAGS = ("monitor", "operate", "led", "orchestrate", "walk", "playball")


class LegacyError(ProtocolError):
    """Bad legacy input, with the code and message of its error reply."""

    def __init__(self, code: ErrorCode, message: str) -> None:
        super().__init__(message)
        self.code = code
        self.message = message


class MessageError(LegacyError):
    """A well-framed message that cannot be applied: answered with an error, connection kept."""


@dataclass(frozen=True)
class Monitor:
    """``monitor``: which streams the client wants pushed, and how often."""

    streams: dict[str, bool]  # only the streams the message names
    period_ms: int | None = None


@dataclass(frozen=True)
class Operate:
    """``operate``: move one joint (or all) to a position in degrees."""

    joint: int | None  # None: every joint (``all`` = 1)
    position_deg: float


@dataclass(frozen=True)
class Led:
    """``led``: set the head or the eye LED to an RGB colour."""

    target: str  # "head" | "eye"
    rgb: tuple[int, int, int]


@dataclass(frozen=True)
class PlayItem:
    """An ``orchestrate`` item playing a motion page (``type`` as the legacy protocol numbers
    it)."""

    page: int
    type: int


@dataclass(frozen=True)
class TimeItem:
    """An ``orchestrate`` item waiting ``seconds`` before the next one."""

    seconds: float


OrchestrateItem = PlayItem | TimeItem


@dataclass(frozen=True)
class Orchestrate:
    """``orchestrate``: a sequence of pages and waits to run in order."""

    items: tuple[OrchestrateItem, ...]


@dataclass(frozen=True)
class OrchestrateStop:
    """``orchestrate`` with ``status`` 0: stop the sequence that runs."""


@dataclass(frozen=True)
class Walk:
    """``walk``: start or change walking at legacy step amplitudes (x, y, turn ``a``), or stop."""

    stop: bool
    x: float
    y: float
    a: float


@dataclass(frozen=True)
class Playball:
    """``playball``: start or stop ball play."""

    start: bool  # decision: client status 0 = start, 1 = stop (the report's text)


Request = Monitor | Operate | Led | Orchestrate | OrchestrateStop | Walk | Playball


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _object(tag: str, value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise MessageError(
            ErrorCode.INVALID, f"{tag}: expected an object of fields, got {_short(value)}"
        )
    return value


def _known(tag: str, fields: dict[str, Any], allowed: tuple[str, ...]) -> None:
    for name in fields:
        if name not in allowed:
            raise MessageError(
                ErrorCode.UNKNOWN,
                f"{tag}: unknown field {name!r}; its fields are {', '.join(allowed)}",
            )


def _present(tag: str, fields: dict[str, Any], name: str) -> Any:
    if name not in fields or fields[name] is None:
        raise MessageError(ErrorCode.INVALID, f"{tag}: missing field {name!r}")
    return fields[name]


def _number(tag: str, fields: dict[str, Any], name: str, low: float, high: float) -> float:
    value = _present(tag, fields, name)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise MessageError(
            ErrorCode.INVALID, f"{tag}: {name} must be a number, got {_short(value)}"
        )
    if not math.isfinite(value):
        raise MessageError(ErrorCode.INVALID, f"{tag}: {name} must be finite, got {value!r}")
    if not low <= value <= high:
        raise MessageError(
            ErrorCode.OUT_OF_RANGE, f"{tag}: {name}={value!r} is outside {low:g}..{high:g}"
        )
    return float(value)


def _integer(tag: str, fields: dict[str, Any], name: str, low: int, high: int | None) -> int:
    value = _present(tag, fields, name)
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int):
        raise MessageError(
            ErrorCode.INVALID, f"{tag}: {name} must be an integer, got {_short(value)}"
        )
    if value < low or (high is not None and value > high):
        bound = f"{low}..{high}" if high is not None else f"{low} or more"
        raise MessageError(ErrorCode.OUT_OF_RANGE, f"{tag}: {name}={value} is outside {bound}")
    return value


def _flag(tag: str, fields: dict[str, Any], name: str) -> bool:
    value = _present(tag, fields, name)
    if value is True or value is False:
        return value
    if isinstance(value, int | float) and value in (0, 1):
        return bool(value)
    raise MessageError(ErrorCode.OUT_OF_RANGE, f"{tag}: {name} must be 0 or 1, got {_short(value)}")


def parse_monitor(value: Any) -> Monitor:
    fields = _object("monitor", value)
    _known("monitor", fields, (*STREAMS, PERIOD_FIELD))
    streams = {name: _flag("monitor", fields, name) for name in STREAMS if name in fields}
    period = None
    if PERIOD_FIELD in fields:
        period = _integer("monitor", fields, PERIOD_FIELD, *PERIOD_MS_RANGE)
    return Monitor(streams, period)


def parse_operate(value: Any) -> Operate:
    fields = _object("operate", value)
    _known("operate", fields, ("all", "id", "position"))
    every = _flag("operate", fields, "all")
    joint = _integer("operate", fields, "id", JOINT_IDS.start, JOINT_IDS.stop - 1)
    position = _number("operate", fields, "position", *POSITION_DEG_RANGE)
    return Operate(None if every else joint, position)


def parse_led(value: Any) -> Led:
    fields = _object("led", value)
    _known("led", fields, ("id", "ledcolor"))
    led_id = _integer("led", fields, "id", 0, None)
    if led_id not in LED_TARGETS:
        raise MessageError(
            ErrorCode.OUT_OF_RANGE,
            f"led: id={led_id} is not an LED; use 26 (forehead) or 27 (eyes)",
        )
    color = _present("led", fields, "ledcolor")
    if not isinstance(color, list) or len(color) != 3:
        raise MessageError(
            ErrorCode.INVALID, f"led: ledcolor must be [red, green, blue], got {_short(color)}"
        )
    r, g, b = (
        _integer("led", {part: c}, part, 0, 255)
        for part, c in zip(("ledcolor red", "ledcolor green", "ledcolor blue"), color, strict=True)
    )
    return Led(LED_TARGETS[led_id], (r, g, b))


def _orchestrate_item(index: int, item: Any) -> OrchestrateItem:
    where = f"orchestrate item {index}"
    fields = _object(where, item)
    if "time" in fields:
        _known(where, fields, ("time",))
        seconds = _number(where, fields, "time", -math.inf, math.inf)
        if seconds <= 1:
            raise MessageError(
                ErrorCode.OUT_OF_RANGE, f"{where}: time={seconds:g} must be greater than 1 second"
            )
        return TimeItem(seconds)
    _known(where, fields, ("page", "type", "time"))
    return PlayItem(
        _integer(where, fields, "page", 1, None), _integer(where, fields, "type", 1, None)
    )


def parse_orchestrate(value: Any) -> Orchestrate | OrchestrateStop:
    if isinstance(value, dict):
        _known("orchestrate", value, ("status",))
        if _integer("orchestrate", value, "status", 0, 1) != 0:
            raise MessageError(
                ErrorCode.INVALID,
                "orchestrate: status 1 is the server's 'started' reply; send a list of "
                "behaviours to start, or status 0 to stop",
            )
        return OrchestrateStop()
    if not isinstance(value, list):
        raise MessageError(
            ErrorCode.INVALID,
            f"orchestrate: expected a list of behaviours or {{'status': 0}}, got {_short(value)}",
        )
    if not value:
        raise MessageError(ErrorCode.INVALID, "orchestrate: the list of behaviours is empty")
    if len(value) > MAX_ORCHESTRATE_ITEMS:
        raise MessageError(
            ErrorCode.OUT_OF_RANGE,
            f"orchestrate: {len(value)} items, at most {MAX_ORCHESTRATE_ITEMS} per list",
        )
    return Orchestrate(tuple(_orchestrate_item(i, item) for i, item in enumerate(value)))


def parse_walk(value: Any) -> Walk:
    fields = _object("walk", value)
    _known("walk", fields, ("a", "stop", "x", "y"))
    stop = _flag("walk", fields, "stop")
    x, y, a = (_number("walk", fields, n, -math.inf, math.inf) for n in ("x", "y", "a"))
    return Walk(stop, x, y, a)


def parse_playball(value: Any) -> Playball:
    fields = _object("playball", value)
    _known("playball", fields, ("status",))
    return Playball(start=not _flag("playball", fields, "status"))


_PARSERS: dict[str, Callable[[Any], Request]] = {
    "monitor": parse_monitor,
    "operate": parse_operate,
    "led": parse_led,
    "orchestrate": parse_orchestrate,
    "walk": parse_walk,
    "playball": parse_playball,
}


def parse_message(value: Any) -> Request:
    """The typed request of one decoded JSON message."""
    if not isinstance(value, dict):
        raise MessageError(
            ErrorCode.INVALID,
            f"a message is a JSON object with one tag ({', '.join(TAGS)}), got {_short(value)}",
        )
    if len(value) != 1:
        tags = ", ".join(map(repr, value)) or "none"
        raise MessageError(
            ErrorCode.INVALID, f"a message carries exactly one tag, this one has: {tags}"
        )
    tag, body = next(iter(value.items()))
    parser = _PARSERS.get(tag)
    if parser is None:
        raise MessageError(
            ErrorCode.UNKNOWN, f"unknown message tag {_short(tag)}; tags are {', '.join(TAGS)}"
        )
    return parser(body)


def error_message(code: ErrorCode | str, message: str) -> dict[str, Any]:
    """The spec's error reply (decision: unknown to old clients, which ignore unknown tags)."""
    return {"error": {"code": str(code), "message": message}}


def status_message(tag: str, status: int) -> dict[str, Any]:
    """``{"orchestrate": {"status": 1}}`` and its playball twin."""
    return {tag: {"status": status}}
