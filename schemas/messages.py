"""Message types on the key space, defined once. Payloads are msgpack maps carrying ``v``
(the schema version) and ``type``; SI units on the wire (rad, rad/s, m/s², V, °C, s).

Use ``encode(msg)`` / ``decode(payload)``; ``decode`` checks the version and the type.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar, overload

import msgpack

from schemas import SCHEMA_VERSION
from schemas.errors import ErrorCode, ProtocolError, brief

# Status's typed sub-maps; importable from here as they always were.
from schemas.status_maps import AlarmInfo as AlarmInfo
from schemas.status_maps import BusInfo as BusInfo
from schemas.status_maps import CameraInfo as CameraInfo
from schemas.status_maps import ChoreographyInfo as ChoreographyInfo
from schemas.status_maps import LeaseInfo as LeaseInfo
from schemas.status_maps import LedsInfo as LedsInfo
from schemas.status_maps import LoopInfo as LoopInfo
from schemas.status_maps import MotionInfo as MotionInfo
from schemas.status_maps import NetworkInfo as NetworkInfo

M = TypeVar("M", bound="Message")

_REGISTRY: dict[str, type[Message]] = {}


@functools.cache
def _field_names(cls: type) -> tuple[str, ...]:
    # dataclasses.fields() rebuilds its tuple on every call; messages go out every tick.
    return tuple(f.name for f in dataclasses.fields(cls))


@dataclass
class Message:
    """A message on the wire: a dataclass with a ``TYPE``, sent as msgpack with its schema
    version."""

    TYPE: ClassVar[str] = ""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.TYPE:
            _REGISTRY[cls.TYPE] = cls

    def to_dict(self) -> dict[str, Any]:
        cls: type = type(self)  # a dataclass's __hash__ is None to mypy; the class is hashable
        d = {name: getattr(self, name) for name in _field_names(cls)}
        d["v"] = SCHEMA_VERSION
        d["type"] = self.TYPE
        return d

    @classmethod
    def from_dict(cls: type[M], d: dict[str, Any]) -> M:
        klass: type = cls  # as in to_dict: hashable, whatever mypy makes of a dataclass type
        names = _field_names(klass)
        return cls(**{k: v for k, v in d.items() if k in names})


def encode(msg: Message) -> bytes:
    payload: bytes = msgpack.packb(msg.to_dict(), use_bin_type=True)
    return payload


def decode_dict(payload: bytes) -> dict[str, Any]:
    try:
        d = msgpack.unpackb(payload, raw=False)
    except Exception as exc:  # msgpack raises several unrelated types
        raise ProtocolError(f"payload is not valid msgpack: {exc}") from exc
    if not isinstance(d, dict):
        raise ProtocolError(f"payload is a {type(d).__name__}, expected a msgpack map")
    return d


def version_refusal(v: object) -> str:
    """The one line a payload of another schema version is refused with: both versions and the
    fix."""
    return (
        f"schema version {brief(v)} not supported: this build of darwin-zenoh speaks "
        f"{SCHEMA_VERSION}; install the same version on both sides "
        "(docs/troubleshooting.md#version-skew)"
    )


@overload
def decode(payload: bytes, expect: type[M]) -> M: ...
@overload
def decode(payload: bytes, expect: None = None) -> Message: ...
def decode(payload: bytes, expect: type[M] | None = None) -> M | Message:
    d = decode_dict(payload)
    v = d.get("v")
    if v != SCHEMA_VERSION:
        raise ProtocolError(version_refusal(v))
    cls = _REGISTRY.get(d.get("type", ""))
    if cls is None:
        raise ProtocolError(f"unknown message type {d.get('type')!r}")
    if expect is not None and cls is not expect:
        raise ProtocolError(f"expected a {expect.TYPE!r} message, got {cls.TYPE!r}")
    return cls.from_dict(d)


@dataclass
class Joints(Message):
    """All joints, columnar: element i of every list is the same joint."""

    TYPE: ClassVar[str] = "joints"
    id: list[int]
    name: list[str]
    position: list[float]  # rad (servo angle after calibration)
    goal: list[float]  # rad
    velocity: list[float]  # rad/s
    load: list[float]  # fraction of max torque, signed
    temperature: list[float]  # °C
    voltage: list[float]  # V
    torque_enabled: list[bool]
    online: list[bool]
    alarm: list[int]  # Dynamixel error bits of the last status packet
    stamp: float = field(default_factory=time.time)  # s since the epoch, when read from the bus
    tick: int = 0

    COLUMNS: ClassVar[tuple[str, ...]] = (
        "id",
        "name",
        "position",
        "goal",
        "velocity",
        "load",
        "temperature",
        "voltage",
        "torque_enabled",
        "online",
        "alarm",
    )


@dataclass
class Imu(Message):
    """The IMU as the daemon read it: gyro and accelerometer, scaled and raw, and the fall
    detector."""

    TYPE: ClassVar[str] = "imu"
    gyro: list[float]  # rad/s, robot axes x, y, z
    accel: list[float]  # m/s², robot axes x, y, z
    gyro_raw: list[int]
    accel_raw: list[int]
    fall: str = "none"  # "none" | "forward" | "backward"
    stamp: float = field(default_factory=time.time)  # s since the epoch, when read from the bus
    tick: int = 0


@dataclass
class CameraFrame(Message):
    """One camera frame, JPEG-encoded."""

    TYPE: ClassVar[str] = "camera_frame"
    jpeg: bytes
    width: int
    height: int
    seq: int
    stamp: float = field(default_factory=time.time)


@dataclass
class Status(Message):
    """Daemon state, ~10 Hz and on change. Sub-maps are typed in :mod:`schemas.status_maps`
    (docs/daemon.md, Status)."""

    TYPE: ClassVar[str] = "status"
    state: str  # starting | scanning | running | degraded | port_lost | servos_off | stopping
    robot: str
    lease: LeaseInfo | None = None
    motion: MotionInfo = field(default_factory=lambda: MotionInfo())
    # The daemon fills motion.choreography; this older place stays empty (clients read both).
    choreography: ChoreographyInfo = field(default_factory=lambda: ChoreographyInfo())
    leds: LedsInfo = field(default_factory=lambda: LedsInfo())
    buttons: dict[str, bool] = field(default_factory=dict)
    bus: BusInfo = field(default_factory=lambda: BusInfo())
    loop: LoopInfo = field(default_factory=lambda: LoopInfo())
    voltage: float = 0.0
    alarms: list[AlarmInfo] = field(default_factory=list)
    stamp: float = field(default_factory=time.time)
    camera: CameraInfo = field(default_factory=lambda: CameraInfo())
    network: NetworkInfo = field(default_factory=lambda: NetworkInfo())
    # The daemon's package version and [major, minor] protocol (schemas/versions.py): every
    # client checks them on connect. Empty from a daemon older than protocol 1.1.
    version: str = ""
    protocol: list[int] = field(default_factory=list)
    # The battery and heat policy (robot_daemon/power_policy.py): PowerInfo and HeatInfo.
    power: dict[str, Any] = field(default_factory=dict)
    heat: dict[str, Any] = field(default_factory=dict)


@dataclass
class Event(Message):
    """Something happened (``…/events``). ``data`` depends on ``kind``; for ``fall`` (from the
    daemon's one fall detector, ``robot_daemon/motion/fall.py``) it is always
    ``{"state": "fallen_forward" | "fallen_backward" | "upright",
    "direction": "forward" | "backward" | "none", "recovering": bool, "page": int | None}``:
    one event when the robot falls, one when it is upright again."""

    TYPE: ClassVar[str] = "event"
    kind: str  # e.g. "lease", "choreography_started", "servo_alarm", "fall", "sound", "fault"
    message: str
    data: dict[str, Any] = field(default_factory=dict)
    seq: int = 0
    stamp: float = field(default_factory=time.time)


@dataclass
class BallDetection(Message):
    """The ball finder's answer for one frame: where the ball is in the image and how far off
    centre."""

    TYPE: ClassVar[str] = "ball"
    found: bool
    x: float = 0.0  # pixel centroid
    y: float = 0.0
    pan_error: float = 0.0  # rad, positive = ball to the robot's left
    tilt_error: float = 0.0  # rad, positive = ball above the image centre
    size: float = 0.0  # fraction of the image area
    width: int = 320
    height: int = 240
    phase: str = ""  # ball play phase when it runs
    stamp: float = field(default_factory=time.time)


@dataclass
class World(Message):
    """The simulated world: the robot's and the ball's places on the field, and whether the robot
    fell."""

    TYPE: ClassVar[str] = "world"
    robot: dict[str, float]  # {"x", "y", "yaw"} metres/radians, field frame
    ball: dict[str, float]  # {"x", "y", "vx", "vy"}
    fallen: str = "none"
    sim_time: float = 0.0
    stamp: float = field(default_factory=time.time)


# ---- arbiter replies ---------------------------------------------------------------------


def ok_reply(verb: str, applied: dict[str, Any] | None = None) -> bytes:
    payload: bytes = msgpack.packb(
        {"v": SCHEMA_VERSION, "ok": True, "verb": verb, "applied": applied or {}},
        use_bin_type=True,
    )
    return payload


def error_reply(
    verb: str,
    code: ErrorCode | str,
    message: str,
    field_: str | None = None,
    retry_after: float | None = None,
) -> bytes:
    """An error reply; ``retry_after`` (s) comes with ``rate_limited``."""
    d: dict[str, Any] = {
        "v": SCHEMA_VERSION,
        "ok": False,
        "verb": verb,
        "code": str(code),
        "message": message,
        "field": field_,
    }
    if retry_after is not None:
        d["retry_after"] = round(float(retry_after), 3)
    payload: bytes = msgpack.packb(d, use_bin_type=True)
    return payload


def command_payload(client: str, **fields: Any) -> bytes:
    """A command query payload: the fields of the verb plus the caller's client id."""
    payload: bytes = msgpack.packb(
        {"v": SCHEMA_VERSION, "client": client, **fields}, use_bin_type=True
    )
    return payload
