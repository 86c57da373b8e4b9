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
Whether a call needs the lease is decided before the handler runs (``needs_lease``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

from schemas.commands import OPS_WITHOUT_LEASE
from schemas.errors import ErrorCode
from schemas.keys import LEASE_FREE_VERBS

if TYPE_CHECKING:
    from config.loader import RobotConfig
    from robot_daemon.arbiter.lease import Lease
    from robot_daemon.motion.interface import JointFrame
    from robot_daemon.motion.manager import MotionManager
    from robot_daemon.services import CameraFeed, DaemonInfo
    from schemas.messages import Message


class Reject(Exception):
    """Refuse a command: becomes an error reply ``{code, message, field}``."""

    def __init__(self, code: ErrorCode | str, message: str, field: str | None = None) -> None:
        super().__init__(message)
        self.code = str(code)
        self.message = message
        self.field = field


@dataclass
class Request:
    verb: str
    client: str  # client id (its liveliness token is …/clients/<client>)
    name: str  # human name of the client
    fields: dict[str, Any] = field(default_factory=dict)


class BusCommands(Protocol):
    """What verb handlers may ask of the bus (the daemon implements it; writes happen between
    bus transactions, in the motion thread)."""

    def set_leds(self, head: int | None, eye: int | None, panel: int | None) -> None: ...
    def set_torque(self, ids: list[int], enable: bool) -> None: ...
    def read_registers(self, dxl_id: int, address: int, length: int) -> bytes: ...
    def write_registers(self, dxl_id: int, address: int, data: bytes) -> None: ...


@dataclass
class MotionContext:
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


Handler = Callable[[Request, MotionContext], dict[str, Any]]

REGISTRY: dict[str, Handler] = {}


def verb(name: str) -> Callable[[Handler], Handler]:
    def deco(fn: Handler) -> Handler:
        if name in REGISTRY and REGISTRY[name] is not fn:
            raise ValueError(f"verb {name!r} is registered twice")
        REGISTRY[name] = fn
        return fn

    return deco


def needs_lease(verb_name: str, fields: dict[str, Any]) -> bool:
    if verb_name in LEASE_FREE_VERBS:
        return False
    op = fields.get("op")
    if verb_name == "registers":
        op = "write" if "data" in fields else "read"
    if verb_name == "walk_params":
        op = "set" if "set" in fields else "read"
    return op not in OPS_WITHOUT_LEASE.get(verb_name, frozenset())
