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

Each verb is declared once, in :data:`SPEC` below: its fields, which of its ops need the lease,
which are reads an observer may send, which are admin-only, whether it is a bus transaction,
and its help line. Every other table (the verbs served, the lease rules, the roles and their
access-control rules, the arbiter's bus budget, the docs' verb table) is derived from it.

A choreography item is ``{"behaviour": id, ...params}`` where params depend on the behaviour's
kind: ``action`` (page), ``walk`` (duration s, x, y, turn), ``sound`` (file/say), ``led``
(head/eye rgb), ``pause`` (duration s), ``head`` (pan, tilt). An item may also be
``{"kind": k, ...params}``, ``{"page": n}``, or a legacy orchestrate item ``{"page": P,
"type": T}`` / ``{"time": S}`` (the ``behaviours`` reply has the ``type`` table). ``choreography``
and ``sound`` take an optional ``lang``: "en" (default) or "pt". ``action`` may name the
page's ``name`` instead of its number; ``walk_params`` ``set`` values are the
``config/walking.toml`` names and units (docs/motion.md).

A ``registers`` write to a register that can disable or lose hardware (``PROTECTED`` in
``robot_daemon/arbiter/protected.py``: power, ID, baud rate, return level and delay, angle,
voltage, temperature and torque limits, alarm shutdown) is ``refused`` unless the daemon runs
with ``--allow-hardware-writes``; other EEPROM needs ``--allow-eeprom``. A write is read back
(an ID write at the new ID) and the reply says what the register holds.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Any


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


@dataclass(frozen=True)
class Verb:
    """Everything about one verb, declared once.

    ``lease``: whether it ever needs the control lease; ``free_ops`` are its ops that do not
    (stopping is always allowed). ``read``: an observer may query it on ``cmd/<verb>`` (it never
    changes anything). ``read_ops``: its read-only ops, sent on ``read/<verb>`` so access
    control can let observers have them while the writes stay on ``cmd/<verb>``. ``admin_ops``:
    ops only an admin may send, on ``admin/<verb>``. ``bus``: a bus transaction in the motion
    thread, inside the arbiter's per-tick bus budget. ``help``: what the docs' verb table says
    of its fields. ``default_op``: what a command without ``op`` does (its handler's default)."""

    name: str
    fields: dict[str, Field]
    help: str
    lease: bool = True
    free_ops: frozenset[str] = frozenset()
    read: bool = False
    read_ops: frozenset[str] = frozenset()
    admin_ops: frozenset[str] = frozenset()
    bus: bool = False
    default_op: str = ""  # the op a command without one does


def _ops(*ops: str) -> frozenset[str]:
    return frozenset(ops)


# The verbs, in the order the docs list them.
SPEC: dict[str, Verb] = {
    v.name: v
    for v in (
        Verb(
            "lease",
            {"op": _op(*(o.value for o in LeaseOp)), "name": Field("str", MAX_NAME)},
            "`op`: acquire \\| release \\| renew \\| status, `name` (the holder's human name)",
            lease=False,
        ),
        Verb(
            "joint",
            {"id": REF, "name": REF, "position": NUMBER, "speed": NUMBER},
            "`id` or `name`, `position` rad (inside the joint's limits, never clamped), `speed` "
            "rad/s (0 or absent = the servo's maximum)",
        ),
        Verb(
            "pose",
            {"positions": Field("map", 32), "duration": NUMBER},
            "`positions` {joint: rad}, `duration` s (cosine-interpolated)",
        ),
        Verb(
            "torque",
            {"enable": BOOL, "ids": Field("list", 32)},
            "`enable`, `ids` (absent = all; enabling holds the present position first)",
            bus=True,
        ),
        Verb(
            "led",
            {"head": RGB, "eye": RGB, "panel": INT},
            "`head` / `eye` [r,g,b] 0..255, `panel` 0..7 (each optional, one at least)",
            bus=True,
        ),
        Verb(
            "halt",
            {},
            "— stop every module and hold (a walk ends at its next double support, within half "
            "a gait period; the rest at once); always taken",
            lease=False,
        ),
        Verb(
            "power",
            {"op": _op("on", "off")},
            "`op`: on (the servos after the reset button: torque back on those that had it, "
            "holding where they are) \\| off (cut DXL power: every servo limp at once)",
            admin_ops=_ops("on", "off"),
            bus=True,
        ),
        Verb(
            "config",
            {},
            "— joints, limits, offsets, gains, tick, walking and IMU settings, robot name",
            lease=False,
            read=True,
        ),
        Verb(
            "registers",
            {"id": INT, "address": INT, "length": INT, "data": Field("list", 128)},
            "`id`, `address`, `length` (read) or `data` (write RAM; EEPROM only with "
            "`--allow-eeprom`; goal writes still inside the limits)",
            free_ops=_ops("read"),
            admin_ops=_ops("write"),
            bus=True,
        ),
        Verb(
            "action",
            {"op": _op("play", "stop", "brake"), "page": INT, "name": Field("str", 64),
             "behaviour": REF},
            "`op`: play \\| stop \\| brake, `page` number or `name`, or `behaviour` id",
            free_ops=_ops("stop", "brake"),
        ),
        Verb(
            "walk",
            {"op": _op("start", "set", "stop"), "x": NUMBER, "y": NUMBER, "turn": NUMBER},
            "`op`: start \\| set \\| stop, `x`, `y` m/s, `turn` rad/s (within the gait's limits)",
            free_ops=_ops("stop"),
        ),
        Verb(
            "walk_params",
            {"set": Field("map", 64)},
            "`set` {name: value} in `config/walking.toml` names and units; absent = read (also "
            "on `read/walk_params`, for observers)",
            free_ops=_ops("read"),
            read_ops=_ops("read"),
        ),
        Verb(
            "trajectory",
            {"op": _op("play", "stop"), "joints": Field("list", 20),
             "points": Field("list", 1000)},
            "`joints` [id-or-name…], `points` [{`t` s from the start, `positions` [rad…]}…] "
            "(checked whole, played in the loop, linear between points) \\| `op`: stop",
            free_ops=_ops("stop"),
        ),
        Verb(
            "head",
            {"op": _op("home"), "pan": NUMBER, "tilt": NUMBER, "track": Field("map", 2)},
            "`pan`, `tilt` rad \\| `track` {pan_error, tilt_error} \\| `op`: home",
        ),
        Verb(
            "choreography",
            {"op": _op("play", "stop"), "items": Field("list", 256), "lang": LANG},
            "`op`: play with `items` [item…] (`lang` en \\| pt) \\| stop",
            free_ops=_ops("stop"),
        ),
        Verb(
            "sound",
            {"file": Field("str", 256), "say": Field("str", 500), "lang": LANG},
            "`file` path \\| `say` text (`lang` en \\| pt)",
        ),
        Verb(
            "playball",
            {"op": _op("start", "stop"), "color": Field("str", 32)},
            "`op`: start \\| stop, `color` name (default red; needs a camera)",
            free_ops=_ops("stop"),
        ),
        Verb(
            "offsets",
            {"op": _op("get", "set"), "offsets": Field("map", 32)},
            "`op`: get (default) \\| set with `offsets` {joint: degrees} (applied live, from "
            "the next goal; the client saves them to the user's config)",
            free_ops=_ops("get"),
            read_ops=_ops("get"),
            admin_ops=_ops("set"),
            default_op="get",
        ),
        Verb(
            "policy",
            {"op": _op("start", "command", "stop", "status"), "rate_hz": NUMBER,
             "mode": Field("str", 16, ("offset", "absolute")), "scale": NUMBER, "x": NUMBER,
             "y": NUMBER, "turn": NUMBER},
            "`op`: start (`rate_hz`, `mode` offset \\| absolute, `scale`: answers the holder a "
            "stream key) \\| command (`x`, `y`, `turn`) \\| stop \\| status (docs/learning.md)",
            free_ops=_ops("stop", "status"),
        ),
        Verb(
            "behaviours",
            {},
            "— the behaviour library and the legacy `type` table",
            lease=False,
            read=True,
        ),
        Verb(
            "pages",
            {"op": _op("list", "get", "put", "delete", "reload", "export", "play"),
             "number": INT, "step": INT, "page": Field("map", 16)},
            "`op`: list \\| get \\| put \\| delete \\| reload \\| export \\| play, `number`, "
            "`page`, `step` (the action-page library: files on the robot)",
            free_ops=_ops("list", "get", "export"),
            admin_ops=_ops("put", "delete", "reload"),
        ),
    )
}

# Verb → its fields: what the arbiter checks every command against (before the lease check and
# the handler), and what a client may send.
COMMAND_FIELDS: dict[str, dict[str, Field]] = {name: v.fields for name, v in SPEC.items()}


def op_of(verb: str, fields: dict[str, Any]) -> str:
    """The operation a command does: its ``op`` field, or for the verbs whose op is implied by
    a field, ``read``/``write`` (registers) and ``read``/``set`` (walk_params)."""
    if verb == "registers":
        return "write" if fields.get("data") is not None else "read"
    if verb == "walk_params":
        return "set" if fields.get("set") is not None else "read"
    op = fields.get("op")
    if isinstance(op, str):
        return op
    spec = SPEC.get(verb)
    return spec.default_op if spec is not None else ""


def needs_lease(verb: str, fields: dict[str, Any]) -> bool:
    """Whether this command needs the control lease: the one rule the arbiter and every
    adapter apply. An unknown verb, or a command with no op where the verb has lease-free
    ops, needs it (the safe answer)."""
    spec = SPEC.get(verb)
    if spec is None:
        return True
    if not spec.lease:
        return False
    op = op_of(verb, fields)
    return not op or op not in spec.free_ops
