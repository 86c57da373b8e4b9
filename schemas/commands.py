"""Arbiter command payloads, one per verb under ``darwin/<robot>/cmd/<verb>``.

Every query payload is a msgpack map ``{"v": SCHEMA_VERSION, "client": <client id>, ...fields}``
(build it with :func:`schemas.messages.command_payload`), optionally with ``client_name``
(the caller's human name, shown as the lease holder; ``name`` is a verb field, e.g. a joint's
name) and ``lease_token`` (the secret ``lease`` op=acquire returned to the holder alone; every
command that needs the lease, ``release`` and ``renew`` must carry it). These are the *envelope*
(:data:`ENVELOPE`); everything else is the verb's own fields, declared once in
:data:`COMMAND_FIELDS`: a field not declared there is refused (``invalid``, naming the field and
the nearest declared name), as is a value of the wrong type or a string/list longer than its
``max_len`` (``out_of_range``). The payload itself is at most 64 KiB (``schemas.query``).

Lease lifetime: the holder proves it is alive with ``lease`` op=``renew`` (with its token) at
least every ``lease.heartbeat_timeout`` (1.5 s; the ``Robot`` client sends one every 0.25 s from a
thread while it holds the lease); without one the daemon ends the lease ("holder silent") and
brings the robot to a safe stop. It also ends when the holder's liveliness token goes, on
``release`` and after ``idle_timeout`` without a command (renewals do not count).

Throttling: each client has a token bucket (``[daemon.arbiter]`` rate/burst, reads separately)
and the loop takes a bounded amount of work per tick; a command over the limit is answered at
once with ``rate_limited`` and ``retry_after`` (s), never queued. ``halt`` is exempt and served
first.
Every reply is either
``{"v": SCHEMA_VERSION, "ok": true, "verb": v, "applied": {...}}`` sent with ``query.reply`` —
*applied* says what was actually applied after conversion — or ``{"v": SCHEMA_VERSION, "ok":
false, "verb": v, "code": c, "message": m, "field": f}`` sent with ``query.reply_err``;
codes are :class:`ErrorCode`.
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

from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Literal

from schemas.errors import ErrorCode, Reject


class LeaseOp(StrEnum):
    ACQUIRE = "acquire"
    RELEASE = "release"
    RENEW = "renew"
    STATUS = "status"


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


NUMBER = Field("number")
INT = Field("int")
BOOL = Field("bool")
REF = Field("ref", 32)
RGB = Field("rgb")
LANG = Field("str", 8, ("en", "pt"))

# Who may send an operation: ``observer`` (a read: it never changes anything), ``operator``,
# ``admin`` (served on ``admin/<verb>``). schemas.roles turns these into keys and roles.
Access = Literal["observer", "operator", "admin"]


@dataclass(frozen=True)
class Op:
    """One operation of a verb, declared once: the verb's fields it takes, whether it needs the
    control lease, and who may send it. A verb without an ``op`` field has one operation named
    "" (or operations chosen by a field's presence: ``when``)."""

    name: str
    fields: tuple[str, ...] = ()
    lease: bool = True
    access: Access = "operator"
    when: str | None = None  # chosen when this field is present and no ``op`` is given

    @property
    def label(self) -> str:
        return self.name or "(no op)"


@dataclass(frozen=True)
class Verb:
    """Everything about one verb, declared once: its fields, its operations (:class:`Op`),
    the one a command without ``op`` does (``default_op``), whether it is a bus transaction
    in the motion thread (inside the arbiter's per-tick bus budget), and what the docs' verb
    table says of its fields (``help``). The lease and role tables are derived from the ops."""

    name: str
    fields: dict[str, Field]
    help: str
    ops: tuple[Op, ...]
    default_op: str = ""
    bus: bool = False
    by_name: dict[str, Op] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "by_name", {o.name: o for o in self.ops})
        for o in self.ops:
            named = (*o.fields, o.when) if o.when else o.fields
            unknown = [f for f in named if f not in self.fields]
            if unknown:
                raise ValueError(f"{self.name} {o.label} names undeclared fields {unknown}")

    @property
    def lease(self) -> bool:
        """Some operation needs the control lease."""
        return any(o.lease for o in self.ops)

    @property
    def free_ops(self) -> frozenset[str]:
        """Operations that do not need the lease, of a verb that otherwise does."""
        return frozenset(o.name for o in self.ops if not o.lease) if self.lease else frozenset()

    @property
    def read(self) -> bool:
        """Every operation is a read: an observer may query it on ``cmd/<verb>``."""
        return all(o.access == "observer" for o in self.ops)

    @property
    def read_ops(self) -> frozenset[str]:
        """The read operations of a verb whose other operations change the robot (they travel
        on ``read/<verb>``, so access control lets observers have them alone)."""
        if self.read:
            return frozenset()
        return frozenset(o.name for o in self.ops if o.access == "observer")

    @property
    def admin_ops(self) -> frozenset[str]:
        """Operations only an admin may send, on ``admin/<verb>``."""
        return frozenset(o.name for o in self.ops if o.access == "admin")


def _only(*fields: str, lease: bool = True, access: Access = "operator") -> tuple[Op, ...]:
    """The one operation of a verb without ``op``."""
    return (Op("", fields, lease, access),)


def _verb(
    name: str,
    fields: dict[str, Field],
    help: str,
    ops: tuple[Op, ...],
    op_field: bool = True,
    **kw: Any,
) -> Verb:
    """A verb whose ``op`` field (when it has named operations and takes one) lists exactly
    its operations."""
    if op_field and any(o.name for o in ops):
        fields = {"op": Field("str", 16, tuple(o.name for o in ops)), **fields}
    return Verb(name, fields, help, ops, **kw)


_PLAY_FIELDS = ("page", "name", "behaviour")
_WALK_FIELDS = ("x", "y", "turn")

# The verbs, in the order the docs list them.
SPEC: dict[str, Verb] = {
    v.name: v
    for v in (
        _verb(
            "lease",
            {"name": Field("str", MAX_NAME)},
            "`op`: acquire \\| release \\| renew \\| status, `name` (the holder's human name)",
            tuple(Op(o.value, ("name",), lease=False) for o in LeaseOp),
            default_op=LeaseOp.STATUS.value,
        ),
        _verb(
            "joint",
            {"id": REF, "name": REF, "position": NUMBER, "speed": NUMBER},
            "`id` or `name`, `position` rad (inside the joint's limits, never clamped), `speed` "
            "rad/s (0 or absent = the servo's maximum)",
            _only("id", "name", "position", "speed"),
        ),
        _verb(
            "pose",
            {"positions": Field("map", 32), "duration": NUMBER},
            "`positions` {joint: rad}, `duration` s (cosine-interpolated)",
            _only("positions", "duration"),
        ),
        _verb(
            "torque",
            {"enable": BOOL, "ids": Field("list", 32)},
            "`enable`, `ids` (absent = all; enabling holds the present position first)",
            _only("enable", "ids"),
            bus=True,
        ),
        _verb(
            "led",
            {"head": RGB, "eye": RGB, "panel": INT},
            "`head` / `eye` [r,g,b] 0..255, `panel` 0..7 (each optional, one at least)",
            _only("head", "eye", "panel"),
            bus=True,
        ),
        _verb(
            "halt",
            {},
            "— stop every module and hold (a walk ends at its next double support, within half "
            "a gait period; the rest at once); always taken",
            _only(lease=False),
        ),
        _verb(
            "power",
            {},
            "`op`: on (the servos after the reset button: torque back on those that had it, "
            "holding where they are) \\| off (cut DXL power: every servo limp at once)",
            (Op("on", access="admin"), Op("off", access="admin")),
            bus=True,
        ),
        _verb(
            "config",
            {},
            "— joints, limits, offsets, gains, tick, walking and IMU settings, robot name",
            _only(lease=False, access="observer"),
        ),
        _verb(
            "registers",
            {"id": INT, "address": INT, "length": INT, "data": Field("list", 128)},
            "`id`, `address`, `length` (read) or `data` (write RAM; EEPROM only with "
            "`--allow-eeprom`; goal writes still inside the limits)",
            (
                Op("read", ("id", "address", "length"), lease=False),
                Op("write", ("id", "address", "data"), access="admin", when="data"),
            ),
            op_field=False,
            default_op="read",
            bus=True,
        ),
        _verb(
            "action",
            {"page": INT, "name": Field("str", 64), "behaviour": REF},
            "`op`: play \\| stop \\| brake, `page` number or `name`, or `behaviour` id",
            (Op("play", _PLAY_FIELDS), Op("stop", lease=False), Op("brake", lease=False)),
            default_op="play",
        ),
        _verb(
            "walk",
            {"x": NUMBER, "y": NUMBER, "turn": NUMBER},
            "`op`: start \\| set \\| stop, `x`, `y` m/s, `turn` rad/s (within the gait's limits)",
            (Op("start", _WALK_FIELDS), Op("set", _WALK_FIELDS), Op("stop", lease=False)),
            default_op="start",
        ),
        _verb(
            "walk_params",
            {"set": Field("map", 64)},
            "`set` {name: value} in `config/walking.toml` names and units; absent = read (also "
            "on `read/walk_params`, for observers)",
            (Op("read", lease=False, access="observer"), Op("set", ("set",), when="set")),
            op_field=False,
            default_op="read",
        ),
        _verb(
            "trajectory",
            {"joints": Field("list", 20), "points": Field("list", 1000)},
            "`joints` [id-or-name…], `points` [{`t` s from the start, `positions` [rad…]}…] "
            "(checked whole, played in the loop, linear between points) \\| `op`: stop",
            (Op("play", ("joints", "points")), Op("stop", lease=False)),
            default_op="play",
        ),
        _verb(
            "head",
            {"pan": NUMBER, "tilt": NUMBER, "track": Field("map", 2)},
            "`pan`, `tilt` rad \\| `track` {pan_error, tilt_error} \\| `op`: home",
            (Op("move", ("pan", "tilt")), Op("track", ("track",), when="track"), Op("home")),
            default_op="move",
        ),
        _verb(
            "choreography",
            {"items": Field("list", 256), "lang": LANG},
            "`op`: play with `items` [item…] (`lang` en \\| pt) \\| stop",
            (Op("play", ("items", "lang")), Op("stop", lease=False)),
            default_op="play",
        ),
        _verb(
            "sound",
            {"file": Field("str", 256), "say": Field("str", 500), "lang": LANG},
            "`file` path \\| `say` text (`lang` en \\| pt)",
            _only("file", "say", "lang"),
        ),
        _verb(
            "playball",
            {"color": Field("str", 32)},
            "`op`: start \\| stop, `color` name (default red; needs a camera)",
            (Op("start", ("color",)), Op("stop", lease=False)),
        ),
        _verb(
            "offsets",
            {"offsets": Field("map", 32)},
            "`op`: get (default) \\| set with `offsets` {joint: degrees} (applied live, from "
            "the next goal; the client saves them to the user's config)",
            (Op("get", lease=False, access="observer"), Op("set", ("offsets",), access="admin")),
            default_op="get",
        ),
        _verb(
            "policy",
            {"rate_hz": NUMBER, "mode": Field("str", 16, ("offset", "absolute")),
             "scale": NUMBER, "x": NUMBER, "y": NUMBER, "turn": NUMBER},
            "`op`: start (`rate_hz`, `mode` offset \\| absolute, `scale`: answers the holder a "
            "stream key) \\| command (`x`, `y`, `turn`) \\| stop \\| status (default; "
            "docs/learning.md)",
            (
                Op("start", ("rate_hz", "mode", "scale")),
                Op("command", _WALK_FIELDS),
                Op("stop", lease=False),
                Op("status", lease=False),
            ),
            default_op="status",
        ),
        _verb(
            "behaviours",
            {},
            "— the behaviour library and the legacy `type` table",
            _only(lease=False, access="observer"),
        ),
        _verb(
            "pages",
            {"number": INT, "step": INT, "page": Field("map", 16)},
            "`op`: list \\| get \\| put \\| delete \\| reload \\| export \\| play, `number`, "
            "`page`, `step` (the action-page library: files on the robot)",
            (
                Op("list", lease=False),
                Op("get", ("number",), lease=False),
                Op("put", ("page",), access="admin"),
                Op("delete", ("number",), access="admin"),
                Op("reload", access="admin"),
                Op("export", lease=False),
                Op("play", ("number", "step")),
            ),
        ),
    )
}

# Verb → its fields: what the arbiter checks every command against (before the lease check and
# the handler), and what a client may send.
COMMAND_FIELDS: dict[str, dict[str, Field]] = {name: v.fields for name, v in SPEC.items()}


def _select(spec: Verb, fields: dict[str, Any]) -> Op | None:
    named = fields.get("op")
    if isinstance(named, str):
        return spec.by_name.get(named)
    for o in spec.ops:
        if o.when is not None and fields.get(o.when) is not None:
            return o
    return spec.by_name.get(spec.default_op)


def operation(verb: str, fields: dict[str, Any]) -> Op:
    """The operation a command does, checked once (the arbiter does it before the lease check
    and hands the result to the handler): its ``op`` field, else the one its fields choose
    (``Op.when``), else the verb's default; and every field it carries must be one of that
    operation's. ``Reject`` names what is wrong."""
    spec = SPEC.get(verb)
    if spec is None:
        return Op("", tuple(fields))  # a verb outside the contract (registry.verb(fields=…))
    chosen = _select(spec, fields)
    if chosen is None:
        names = " | ".join(o.name for o in spec.ops if not o.when)
        given = fields.get("op")
        what = f"unknown op {given!r}" if given is not None else "no op"
        raise Reject(ErrorCode.INVALID, f"{verb}: {what}; op is one of {names}", "op")
    extra = sorted(k for k, v in fields.items() if v is not None and k != "op"
                   and k not in chosen.fields)
    if extra:
        takes = ", ".join(chosen.fields) or "none"
        raise Reject(
            ErrorCode.INVALID,
            f"{verb} {chosen.label} takes no field {extra[0]!r} (its fields: {takes})",
            extra[0],
        )
    return chosen


def op_of(verb: str, fields: dict[str, Any]) -> str:
    """The name of the operation a command does (its ``op``, the one its fields choose, or
    the verb's default), unchecked: "" when there is none."""
    spec = SPEC.get(verb)
    chosen = _select(spec, fields) if spec is not None else None
    if chosen is not None:
        return chosen.name
    named = fields.get("op")
    return named if isinstance(named, str) else ""


def needs_lease(verb: str, fields: dict[str, Any]) -> bool:
    """Whether this command needs the control lease: the one rule the arbiter and every
    adapter apply. An unknown verb, or a command with no op where the verb has lease-free
    ops, needs it (the safe answer)."""
    spec = SPEC.get(verb)
    if spec is None:
        return True
    chosen = _select(spec, fields)
    return chosen.lease if chosen is not None else spec.lease
