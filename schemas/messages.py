"""Message types on the key space, defined once. Payloads are msgpack maps carrying ``v``
(the schema version) and ``type``; SI units on the wire (rad, rad/s, m/s², V, °C, s).

Use ``encode(msg)`` / ``decode(payload)``; ``decode`` checks the version and the type.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypedDict, TypeVar

import msgpack

from schemas import SCHEMA_VERSION
from schemas.errors import ErrorCode, ProtocolError

M = TypeVar("M", bound="Message")

_REGISTRY: dict[str, type[Message]] = {}


@functools.cache
def _field_names(cls: type) -> tuple[str, ...]:
    # dataclasses.fields() rebuilds its tuple on every call; messages go out every tick.
    return tuple(f.name for f in dataclasses.fields(cls))


@dataclass
class Message:
    TYPE: ClassVar[str] = ""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.TYPE:
            _REGISTRY[cls.TYPE] = cls

    def to_dict(self) -> dict[str, Any]:
        d = {name: getattr(self, name) for name in _field_names(type(self))}
        d["v"] = SCHEMA_VERSION
        d["type"] = self.TYPE
        return d

    @classmethod
    def from_dict(cls: type[M], d: dict[str, Any]) -> M:
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})


def encode(msg: Message) -> bytes:
    return msgpack.packb(msg.to_dict(), use_bin_type=True)


def decode_dict(payload: bytes) -> dict[str, Any]:
    try:
        d = msgpack.unpackb(payload, raw=False)
    except Exception as exc:  # msgpack raises several unrelated types
        raise ProtocolError(f"payload is not valid msgpack: {exc}") from exc
    if not isinstance(d, dict):
        raise ProtocolError(f"payload is a {type(d).__name__}, expected a msgpack map")
    return d


def decode(payload: bytes, expect: type[M] | None = None) -> M | Message:
    d = decode_dict(payload)
    v = d.get("v")
    if v != SCHEMA_VERSION:
        raise ProtocolError(
            f"schema version {v!r} not supported (this build speaks {SCHEMA_VERSION})"
        )
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
    position_deg: list[float]
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
        "position_deg",
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
    TYPE: ClassVar[str] = "camera_frame"
    jpeg: bytes
    width: int
    height: int
    seq: int
    stamp: float = field(default_factory=time.time)


# ---- the sub-maps of Status, typed so clients read known keys (msgpack carries plain maps) ----


class LeaseInfo(TypedDict):
    """Who holds the control lease (never its secret token)."""

    client: str
    name: str
    since: float  # s since the epoch


class ArbiterCounts(TypedDict, total=False):
    accepted: int
    rejected: int
    errors: int
    rate_limited: int


class BusInfo(TypedDict, total=False):
    port: str
    open: bool
    bulk_reads: int
    missing_replies: int
    corrupt_replies: int
    retries: int
    stale_ticks: int
    bus_stalls: int
    sync_writes: int
    goal_writes: int
    skipped_goals: int
    limit_clamps: int
    port_reopens: int
    offline: list[int]
    torque_off: list[int]
    cm730_online: bool
    warnings: list[str]
    bytes_written: int
    bytes_read: int
    bus_errors: int
    arbiter: ArbiterCounts


class LoopInfo(TypedDict, total=False):
    tick_ms: float
    ticks: int
    period_p50_ms: float
    period_p99_ms: float
    period_max_ms: float
    bus_p50_ms: float
    bus_p99_ms: float
    work_p99_ms: float
    overruns: int  # ticks whose work ran past the next deadline
    skipped: int  # deadlines given up after overruns
    # The alarm: sustained overruns (robot_daemon/loop_stats.py says how they are judged);
    # every UI shows it. overrun_pct: share of the ticks that overran in the last window.
    overloaded: bool
    overrun_pct: float
    scheduling: str
    events_dropped: int  # events the publisher's queue had no room for


class CameraInfo(TypedDict, total=False):
    source: str
    subscribed: bool
    captured: int
    published: int
    errors: int
    last_error: str | None
    fps: float
    width: int
    height: int
    opened: int  # times the source was opened (one owner: once while anyone needs frames)
    readers: int  # in-process frame readers (ball vision)
    passed_through: int  # published as the source's own JPEG (V4L2 MJPEG, the sim world)


class NetworkInfo(TypedDict, total=False):
    """Where the daemon is on the network (``darwin list`` shows ``endpoint``)."""

    endpoint: str  # where clients reach this robot: its router when it joined one, else its own
    router: str | None  # the router it joined (``--router``); None: it is the meeting point
    listen: list[str]  # its own listen endpoints (none when it only joined a router)


class AlarmInfo(TypedDict):
    id: int
    bits: int


class LedsInfo(TypedDict, total=False):
    """The CM-730's LEDs as read back (empty before it answered)."""

    head: list[int]  # RGB 0..255
    eye: list[int]
    panel: int  # bit mask of the three panel LEDs


# ``status.motion``: the joint owners and one map per motion module (robot_daemon/motion/).
class ActionInfo(TypedDict):
    active: bool
    playing: bool
    page: int | None
    name: str | None
    step: int | None  # 1-based
    stopping: bool


class WalkAxes(TypedDict):
    x_mm: float
    y_mm: float
    turn_deg: float


class WalkSpeed(TypedDict):
    x: float  # m/s
    y: float
    turn: float  # rad/s


class WalkingInfo(TypedDict):
    active: bool
    walking: bool
    stopping: bool
    command: WalkAxes  # what was asked
    amplitude: WalkAxes  # what the gait runs now (latched at step boundaries)
    speed: WalkSpeed
    phase_ms: float
    steps: int
    skipped_ticks: int


class HeadInfo(TypedDict):
    active: bool
    mode: str  # idle | move | track
    target_deg: list[float] | None  # [pan, tilt]
    current_deg: list[float] | None


class DirectInfo(TypedDict):
    active: bool
    moving: bool
    joints: list[int]


class FallInfo(TypedDict):
    active: bool
    state: str
    falls: int
    recover: bool


class ImuCalibrationInfo(TypedDict):
    active: bool
    calibrated: bool  # the gyro centre is measured; falls and walking balance wait for it
    gyro_centre: list[float]  # counts at rest, x y z (robot axes); 512 until calibrated
    attempts: int


class BallSeen(TypedDict):
    found: bool
    pan: float  # rad
    tilt: float


class BallStep(TypedDict):
    step_mm: float
    turn_deg: float


class BallPlayInfo(TypedDict):
    active: bool
    phase: str  # the phases of robot_daemon/motion/ball/module.py
    color: str
    kicks: int
    frames: int
    ball: BallSeen | None
    walk: BallStep


class ChoreographyInfo(TypedDict, total=False):
    active: bool
    playing: bool
    run: int
    index: int | None
    count: int
    item: str | None
    items: list[str]
    last_result: str | None


class PolicyInfo(TypedDict):
    active: bool
    state: str  # idle | running | holding | damping | stopped (schemas/policy.py)
    reason: str  # why it stopped


class MotionInfo(TypedDict, total=False):
    owners: dict[str, str]  # joint id → the module that drives it
    imu: ImuCalibrationInfo
    fall: FallInfo
    action: ActionInfo
    head: HeadInfo
    walking: WalkingInfo
    direct: DirectInfo
    ball: BallPlayInfo
    choreography: ChoreographyInfo
    policy: PolicyInfo


@dataclass
class Status(Message):
    """Daemon state, ~10 Hz and on change. Sub-maps are typed above (docs/daemon.md, Status)."""

    TYPE: ClassVar[str] = "status"
    state: str  # starting | scanning | running | degraded | port_lost | stopping
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
    TYPE: ClassVar[str] = "world"
    robot: dict[str, float]  # {"x", "y", "yaw"} metres/radians, field frame
    ball: dict[str, float]  # {"x", "y", "vx", "vy"}
    fallen: str = "none"
    sim_time: float = 0.0
    stamp: float = field(default_factory=time.time)


# ---- arbiter replies ---------------------------------------------------------------------


def ok_reply(verb: str, applied: dict[str, Any] | None = None) -> bytes:
    return msgpack.packb(
        {"v": SCHEMA_VERSION, "ok": True, "verb": verb, "applied": applied or {}},
        use_bin_type=True,
    )


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
    return msgpack.packb(d, use_bin_type=True)


def command_payload(client: str, **fields: Any) -> bytes:
    """A command query payload: the fields of the verb plus the caller's client id."""
    return msgpack.packb({"v": SCHEMA_VERSION, "client": client, **fields}, use_bin_type=True)
