"""Arbiter command payloads, one per verb under ``darwin/<robot>/cmd/<verb>``.

Every query payload is a msgpack map ``{"v": 1, "client": <client id>, ...fields}`` (build it
with :func:`schemas.messages.command_payload`), optionally with ``client_name`` (the caller's
human name, shown as the lease holder; ``name`` is a verb field, e.g. a joint's name) and
``lease_token`` (the secret ``lease`` op=acquire returned to the holder alone; every command that
needs the lease, ``release`` and ``renew`` must carry it). These are the *envelope*
(:data:`ENVELOPE`); everything else is the verb's own fields, declared once in
:data:`COMMAND_FIELDS`: a field not declared there is refused (``invalid``, naming the field and
the nearest declared name), as is a value of the wrong type or a string/list longer than its
``max_len`` (``out_of_range``). The payload itself is at most 64 KiB (``schemas.query``).

Lease lifetime: the holder proves it is alive with ``lease`` op=``renew`` (with its token) at
least every ``lease.heartbeat_timeout`` (1.5 s; the ``Robot`` client sends one every 0.4 s from a
thread while it holds the lease); without one the daemon ends the lease ("holder silent") and
brings the robot to a safe stop. It also ends when the holder's liveliness token goes, on
``release`` and after ``idle_timeout`` without a command (renewals do not count).

Throttling: each client has a token bucket (``[daemon.arbiter]`` rate/burst, reads separately)
and the loop takes a bounded amount of work per tick; a command over the limit is answered at
once with ``rate_limited`` and ``retry_after`` (s), never queued. ``halt`` is exempt and served
first.
Every reply is either
``{"v":1, "ok": true, "verb": v, "applied": {...}}`` sent with ``query.reply`` — *applied* says
what was actually applied after conversion — or ``{"v":1, "ok": false, "verb": v, "code": c,
"message": m, "field": f}`` sent with ``query.reply_err``; codes are :class:`ErrorCode`.
Angles are rad, speeds rad/s or m/s, durations s. Joints are named by id (1..20) or name.

| verb | fields | lease |
|---|---|---|
| lease | op: "acquire" \\| "release" \\| "renew" \\| "status", name: str (human) | no |
| joint | id \\| name, position: rad, speed: rad/s (optional, 0 = servo max) | yes |
| pose | positions: {id-or-name: rad}, duration: s (> 0, interpolated) | yes |
| torque | enable: bool, ids: [id-or-name] (absent = all) | yes |
| led | head: [r,g,b] 0..255, eye: [r,g,b], panel: 0..7 (each optional, ≥ 1 present) | yes |
| halt | — (stop every motion module, hold the present pose) | never |
| config | — → joints, limits, offsets, tick period, walk params, robot name | no |
| registers | id, address, length (read) \\| id, address, data: [bytes] (write; see below) | write |
| action | op: "play" \\| "stop" \\| "brake", page: int \\| name: str \\| behaviour: id | play |
| walk | op: "start" \\| "set" \\| "stop", x: m/s, y: m/s, turn: rad/s | start/set |
| walk_params | set: {name: value} (absent = read, also on ``read/walk_params``) | set |
| head | pan: rad, tilt: rad \\| track: {pan_error, tilt_error} \\| op: "home" | yes |
| choreography | op: "play", items: [item…] \\| op: "stop" | play |
| sound | file: path \\| say: text | yes |
| playball | op: "start" \\| "stop", color: name (default "red") | start |
| behaviours | — → the behaviour library and the legacy ``type`` table | no |
| pages | op: list, get, put, delete, reload, export, play; number, page, step | put… |
| policy | op: "start" (rate_hz, mode, scale) \\| "command" (x, y, turn) \\| "stop" | start |

A choreography item is ``{"behaviour": id, ...params}`` where params depend on the behaviour's
kind: ``action`` (page), ``walk`` (duration s, x, y, turn), ``sound`` (file/say), ``led``
(head/eye rgb), ``pause`` (duration s), ``head`` (pan, tilt). An item may also be
``{"kind": k, ...params}``, ``{"page": n}``, or a legacy orchestrate item ``{"page": P,
"type": T}`` / ``{"time": S}`` (the ``behaviours`` reply has the ``type`` table). ``choreography``
and ``sound`` take an optional ``lang``: "en" (default) or "pt". ``action`` may name the
page's ``name`` instead of its number; ``walk_params`` ``set`` values are the
``config/walking.toml`` names and units (README, "Motion").

A ``registers`` write to a register that can disable or lose hardware (``PROTECTED`` in
``robot_daemon/arbiter/protected.py``: power, ID, baud rate, return level and delay, angle,
voltage, temperature and torque limits, alarm shutdown) is ``refused`` unless the daemon runs
with ``--allow-hardware-writes``; other EEPROM needs ``--allow-eeprom``. A write is read back
(an ID write at the new ID) and the reply says what the register holds.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


class LeaseOp(StrEnum):
    ACQUIRE = "acquire"
    RELEASE = "release"
    RENEW = "renew"
    STATUS = "status"


class MotionOp(StrEnum):
    PLAY = "play"
    START = "start"
    SET = "set"
    STOP = "stop"
    BRAKE = "brake"
    HOME = "home"


# Verb → ops that are allowed without the lease (stopping is always allowed).
OPS_WITHOUT_LEASE: dict[str, frozenset[str]] = {
    "action": frozenset({"stop", "brake"}),
    "walk": frozenset({"stop"}),
    "choreography": frozenset({"stop"}),
    "playball": frozenset({"stop"}),
    "registers": frozenset({"read"}),
    "walk_params": frozenset({"read"}),
    "pages": frozenset({"list", "get", "export"}),
    "policy": frozenset({"stop", "status"}),
}


# Fields of every command that are not the verb's own.
ENVELOPE: tuple[str, ...] = ("v", "client", "client_name", "lease_token")
MAX_CLIENT_ID = 64
MAX_NAME = 64
TOKEN_BYTES = 16  # the lease secret: 16 random bytes, URL-safe text on the wire


@dataclass(frozen=True)
class Field:
    """One verb field: its kind, and for strings/lists/maps the longest allowed.

    kinds: ``int``, ``number`` (int or float, finite), ``bool``, ``str``, ``ref`` (an id or a
    name: int or str), ``rgb`` ([r, g, b]), ``list``, ``map``. ``None`` always means absent."""

    kind: str
    max_len: int | None = None
    choices: tuple[str, ...] | None = None


def _op(*choices: str) -> Field:
    return Field("str", 16, choices)


NUMBER = Field("number")
INT = Field("int")
BOOL = Field("bool")
REF = Field("ref", 32)
RGB = Field("rgb")
LANG = Field("str", 8, ("en", "pt"))

# Verb → its fields: the one declaration the arbiter checks every command against (before the
# lease check and the handler), and what a client may send.
COMMAND_FIELDS: dict[str, dict[str, Field]] = {
    "lease": {"op": _op(*(o.value for o in LeaseOp)), "name": Field("str", MAX_NAME)},
    "joint": {"id": REF, "name": REF, "position": NUMBER, "speed": NUMBER},
    "pose": {"positions": Field("map", 32), "duration": NUMBER},
    "torque": {"enable": BOOL, "ids": Field("list", 32)},
    "led": {"head": RGB, "eye": RGB, "panel": INT},
    "halt": {},
    "config": {},
    "registers": {"id": INT, "address": INT, "length": INT, "data": Field("list", 128)},
    "action": {
        "op": _op("play", "stop", "brake"),
        "page": INT,
        "name": Field("str", 64),
        "behaviour": REF,
    },
    "walk": {"op": _op("start", "set", "stop"), "x": NUMBER, "y": NUMBER, "turn": NUMBER},
    "walk_params": {"set": Field("map", 64)},
    "head": {"op": _op("home"), "pan": NUMBER, "tilt": NUMBER, "track": Field("map", 2)},
    "choreography": {"op": _op("play", "stop"), "items": Field("list", 256), "lang": LANG},
    "sound": {"file": Field("str", 256), "say": Field("str", 500), "lang": LANG},
    "playball": {"op": _op("start", "stop"), "color": Field("str", 32)},
    "behaviours": {},
    "pages": {
        "op": _op("list", "get", "put", "delete", "reload", "export", "play"),
        "number": INT,
        "step": INT,
        "page": Field("map", 16),
    },
    # The policy stream (schemas/policy.py): start answers the holder a stream key.
    "policy": {
        "op": _op("start", "command", "stop", "status"),
        "rate_hz": NUMBER,
        "mode": Field("str", 16, ("offset", "absolute")),
        "scale": NUMBER,
        "x": NUMBER,
        "y": NUMBER,
        "turn": NUMBER,
    },
}
