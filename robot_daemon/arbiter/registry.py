"""Verb handlers: how a module adds a command to the arbiter.

    from robot_daemon.arbiter.registry import verb, Request, MotionContext
    from robot_daemon.arbiter import fields as F

    @verb("head")
    def head(req: Request, ctx: MotionContext) -> dict:
        pan = F.number(req.fields, "pan", -1.2, 1.2)
        ...
        return {"pan": pan}

A handler raises :class:`Reject` (usually through the ``fields`` helpers) to answer an error;
anything else it raises is reported as an ``internal`` error and logged, never crashes the loop.

Each verb's fields are declared once, in ``schemas.commands.COMMAND_FIELDS`` (or with
``@verb(name, fields={...})`` for a verb that is not in the contract yet). :func:`check_fields`
runs before anything else: an undeclared field, a wrong type or an over-long string/list is
refused naming the field, so a handler only ever sees declared fields of the declared kinds.
Its operation is worked out next, once (``schemas.commands.operation``: the ``op`` field, the
field that implies one, or the verb's default; a field the operation does not take is refused),
and whether it needs the lease is the operation's (``Op.lease``), checked before the handler
runs. The handler gets the operation as ``req.op`` and never parses ``op`` itself.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

from config.loader import nearest
from schemas.commands import COMMAND_FIELDS, Field, Op, needs_lease, operation
from schemas.errors import ErrorCode, Reject, brief

if TYPE_CHECKING:
    from config.loader import RobotConfig
    from robot_daemon.arbiter.lease import Lease
    from robot_daemon.bus.calibration import Calibration
    from robot_daemon.frames import JointFrame
    from robot_daemon.motion.manager import MotionManager
    from robot_daemon.services import CameraFeed, DaemonInfo
    from schemas.messages import Message


__all__ = [
    "REGISTRY", "BusCommands", "MotionContext", "Op", "Reject", "Request", "needs_lease", "verb",
]

M = TypeVar("M")


_UNRESOLVED = Op("?")


@dataclass
class Request:
    """A checked command. ``op`` is its operation, worked out once from the spec
    (:func:`schemas.commands.operation`): handlers branch on ``req.op.name`` and never read
    the ``op`` field."""

    verb: str
    client: str  # client id (its liveliness token is …/clients/<client>)
    name: str  # human name of the client
    fields: dict[str, Any] = field(default_factory=dict)
    token: str | None = None  # the lease secret, when the caller holds the lease
    op: Op = _UNRESOLVED  # worked out from the fields when not given

    def __post_init__(self) -> None:
        if self.op is _UNRESOLVED:
            self.op = operation(self.verb, self.fields)


class BusCommands(Protocol):
    """What verb handlers may ask of the bus (the daemon implements it; writes happen between
    bus transactions, in the motion thread)."""

    def set_leds(self, head: int | None, eye: int | None, panel: int | None) -> None: ...
    def set_torque(self, ids: list[int], enable: bool) -> dict[int, str]: ...
    def read_registers(self, dxl_id: int, address: int, length: int) -> bytes: ...
    def write_registers(self, dxl_id: int, address: int, data: bytes) -> None: ...

    calibration: Calibration  # joint ↔ servo conversion; the offsets verb changes it live


@dataclass
class MotionContext:
    """What a verb's handler may read and call: the robot, its motion and bus, the config, the
    latest frame."""

    robot: RobotConfig
    manager: MotionManager
    bus: BusCommands
    settings: dict[str, Any]  # the merged config (all sections)
    frame: JointFrame | None  # latest sensor frame, None before the first tick
    emit: Callable[..., None]  # emit(kind, message, **data) → …/events
    # The narrow views of the daemon a handler may use (None where there is no daemon, e.g.
    # unit tests, or no such device):
    lease: Lease | None = None  # the control lease
    camera: CameraFeed | None = None  # the one camera owner's frames; None without a camera
    publish: Callable[[str, Message], None] | None = None  # publish(topic, msg), newest only
    info: DaemonInfo | None = None  # the daemon's name and period
    extras: dict[str, Any] = field(default_factory=dict)  # options, e.g. "allow_eeprom"
    power: PowerSwitch | None = None  # the servos' power switch (the daemon's bus supervisor)

    def module(self, name: str, kind: type[M], what: str = "") -> M:
        """The motion module ``name``, a ``kind``; ``Reject`` (unavailable) when this daemon
        runs without it (``what`` names it for people, default "the <name> module")."""
        found = self.manager.get(name)
        if not isinstance(found, kind):
            raise Reject(
                ErrorCode.UNAVAILABLE, f"{what or f'the {name} module'} is not part of this daemon"
            )
        return found


class PowerSwitch(Protocol):
    """The servos' power (DXL_POWER through the CM-730), as the ``power`` verb may use it."""

    def ask_power(self, on: bool, by: str) -> dict[str, Any]: ...


Handler = Callable[[Request, MotionContext], dict[str, Any]]

REGISTRY: dict[str, Handler] = {}
SPECS: dict[str, dict[str, Field]] = {}


def verb(name: str, fields: dict[str, Field] | None = None) -> Callable[[Handler], Handler]:
    spec = fields if fields is not None else COMMAND_FIELDS.get(name)
    if spec is None:
        raise ValueError(
            f"verb {name!r} declares no fields: add it to schemas.commands.COMMAND_FIELDS "
            "(or pass fields= to @verb)"
        )

    def deco(fn: Handler) -> Handler:
        if name in REGISTRY and REGISTRY[name] is not fn:
            raise ValueError(f"verb {name!r} is registered twice")
        REGISTRY[name] = fn
        SPECS[name] = spec
        return fn

    return deco


def check_fields(verb_name: str, fields: dict[str, Any]) -> None:
    """Refuse an undeclared field, a wrong type or an over-long value (naming the field)."""
    spec = SPECS.get(verb_name, COMMAND_FIELDS.get(verb_name, {}))
    for name, value in fields.items():
        f = spec.get(name)
        if f is None:
            near = nearest(str(name), spec, cutoff=0.6)
            hint = f"; did you mean {near!r}?" if near else ""
            known = ", ".join(spec) or "none"
            raise Reject(
                ErrorCode.INVALID,
                f"unknown field {brief(name)} for {verb_name} (fields: {known}){hint}",
                str(name)[:64],
            )
        if value is not None:
            _check_kind(name, f, value)


_KINDS: dict[str, tuple[str, Callable[[Any], bool]]] = {
    "int": ("an integer", lambda v: isinstance(v, int) and not isinstance(v, bool)),
    "number": (
        "a finite number",
        lambda v: isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v),
    ),
    "bool": ("true or false", lambda v: isinstance(v, bool)),
    "str": ("a string", lambda v: isinstance(v, str)),
    "ref": (
        "an id or a name",
        lambda v: (isinstance(v, int) and not isinstance(v, bool)) or isinstance(v, str),
    ),
    "rgb": (
        "[r, g, b]",
        lambda v: isinstance(v, list | tuple)
        and len(v) == 3
        and all(isinstance(c, int) and not isinstance(c, bool) for c in v),
    ),
    "list": ("a list", lambda v: isinstance(v, list | tuple)),
    "map": ("a map", lambda v: isinstance(v, dict)),
}


def _check_kind(name: str, f: Field, value: Any) -> None:
    what, ok = _KINDS[f.kind]
    if not ok(value):
        raise Reject(ErrorCode.INVALID, f"{name} must be {what}, got {brief(value)}", name)
    sized = isinstance(value, str | list | tuple | dict)
    if f.max_len is not None and sized and len(value) > f.max_len:
        unit = "characters" if isinstance(value, str) else "entries"
        raise Reject(ErrorCode.OUT_OF_RANGE, f"{name} is longer than {f.max_len} {unit}", name)
    if f.choices is not None and value not in f.choices:
        raise Reject(
            ErrorCode.INVALID, f"{name}={brief(value)} is not one of {', '.join(f.choices)}", name
        )
