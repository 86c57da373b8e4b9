"""The sub-maps of the daemon's ``status`` message (:class:`schemas.messages.Status`), typed
so clients read known keys: msgpack carries them as plain maps. Each key is documented in
docs/daemon.md (Status).
"""

# No `from __future__ import annotations`: a TypedDict compiles each annotation given as a
# string into a ForwardRef, and this module's ~130 keys cost the daemon, the emulator and the
# gateway ~2.7 ms of CPU at each start that way; as objects (all builtins) they cost half.
from typing import TypedDict


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
    # The alarm: sustained overruns (robot_daemon/engine/loop_stats.py says how they are judged);
    # every UI shows it. overrun_pct: share of the ticks that overran in the last window.
    overloaded: bool
    overrun_pct: float
    scheduling: str
    events_dropped: int  # events the publisher's queue had no room for
    telemetry_hz: float  # joints and imu at most this often ([daemon] telemetry_hz); 0: every tick


class CameraInfo(TypedDict, total=False):
    source: str
    subscribed: bool
    capturing: bool  # the capture thread is running; counts settle once it is False
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
