"""The messages the daemon broadcasts: joints and IMU each tick, status at its rate.

Each is built from the tick's :class:`~robot_daemon.engine.snapshot.TickSnapshot`; status also
from a :class:`StatusSources`, the few long-lived parts it reports on (not the daemon). Joints
and IMU go out every tick, so their bytes come from a layout packed once
(:class:`schemas.packed.Prepacked`: the bytes ``encode`` would give, at a fraction of the cost).
"""

from __future__ import annotations

from dataclasses import dataclass
from operator import itemgetter
from typing import TYPE_CHECKING, Any, cast

from robot_daemon.bus.state import cm730_status
from robot_daemon.hotpath import compiled as _compiled
from schemas.messages import Imu, Joints, Message, Status, encode
from schemas.packed import Prepacked
from schemas.status_maps import (
    AlarmInfo,
    BusInfo,
    CameraInfo,
    LeaseInfo,
    LoopInfo,
    MotionInfo,
    NetworkInfo,
)
from schemas.versions import PACKAGE_VERSION

if TYPE_CHECKING:
    from config.loader import RobotConfig
    from robot_daemon.arbiter.core import Arbiter
    from robot_daemon.arbiter.lease import Lease
    from robot_daemon.bus.robot_bus import RobotBus
    from robot_daemon.engine.camera import CameraThread
    from robot_daemon.engine.loop_stats import LoopStats
    from robot_daemon.engine.power_actions import PowerGuard
    from robot_daemon.engine.snapshot import TickSnapshot
    from robot_daemon.motion.manager import MotionManager

_NO_CAMERA = {"source": "none", "captured": 0, "subscribed": False, "capturing": False}


class JointsEncoder:
    """The joints message of a snapshot, for one robot's joints: as bytes each tick."""

    def __init__(self, robot: RobotConfig) -> None:
        ids = robot.ids
        # A run of IDs (the DARwIn-OP's 1…20) is a slice of every list; else a pick by id.
        run = bool(ids) and ids == tuple(range(ids[0], ids[-1] + 1))
        self.at: slice | list[int] = slice(ids[0], ids[-1] + 1) if run else list(ids)
        self.ids, self.names = list(ids), list(robot.names)
        self.layout = Prepacked(Joints, {"id": self.ids, "name": self.names})
        # The slice as one C call (nine a tick), no Python frame of its own.
        self._slice = itemgetter(self.at) if run else None

    def pick(self, values: list[Any]) -> list[Any]:
        """The joints' values out of a list by joint id."""
        if self._slice is not None:
            picked: list[Any] = self._slice(values)
            return picked
        at = self.at
        return values[at] if isinstance(at, slice) else [values[j] for j in at]

    def values(self, snap: TickSnapshot) -> dict[str, Any]:
        """The message's fields that change, by name, in its order (what ``encode`` packs)."""
        pick = self._slice or self.pick
        return {
            "position": pick(snap.position),
            "goal": pick(snap.goal),
            "velocity": pick(snap.velocity),
            "load": pick(snap.load),
            "temperature": pick(snap.temperature),
            "voltage": pick(snap.voltage),
            "torque_enabled": pick(snap.torque),
            "online": pick(snap.online),
            "alarm": pick(snap.alarm),
            "stamp": snap.stamp,
            "tick": snap.tick,
        }

    def message(self, snap: TickSnapshot) -> Joints:
        return Joints(id=list(self.ids), name=list(self.names), **self.values(snap))

    def encode(self, snap: TickSnapshot) -> bytes:
        pick = self._slice or self.pick
        # values()'s fields in its order, as a list (no dict: this runs every tick)
        values = [pick(snap.position), pick(snap.goal), pick(snap.velocity), pick(snap.load),
                  pick(snap.temperature), pick(snap.voltage), pick(snap.torque),
                  pick(snap.online), pick(snap.alarm), snap.stamp, snap.tick]
        return _pack(self.layout, values)


def _pack(layout: Prepacked, values: list[Any]) -> bytes:
    """The layout's bytes, by the compiled packer where it is built and takes these values
    (robot_daemon/hotpath.py), else by msgpack through the layout."""
    if _compiled is not None and layout.single is not None:
        head, keys, tail = layout.single
        out = _compiled.pack_fields(head, keys, values, tail)
        if out is not NotImplemented:
            return cast(bytes, out)
    return layout.pack(values)


_IMU_LAYOUT = Prepacked(Imu, {})


def imu_message(snap: TickSnapshot) -> Imu:
    return Imu(
        gyro=list(snap.gyro),
        accel=list(snap.accel),
        gyro_raw=list(snap.gyro_raw),
        accel_raw=list(snap.accel_raw),
        fall=snap.fall,
        stamp=snap.stamp,
        tick=snap.tick,
    )


def imu_payload(snap: TickSnapshot) -> bytes:
    """:func:`imu_message`'s bytes, from the packed layout (the motion thread's only)."""
    return _pack(
        _IMU_LAYOUT,
        [snap.gyro, snap.accel, snap.gyro_raw, snap.accel_raw, snap.fall, snap.stamp, snap.tick],
    )


@dataclass(frozen=True)
class StatusSources:
    """What status reports on besides the tick's snapshot: the parts, each asked for its own
    status, and the facts fixed at start."""

    robot: RobotConfig
    name: str  # the robot's name in the key space
    protocol: tuple[int, int]
    network: NetworkInfo
    lease: Lease
    manager: MotionManager
    bus: RobotBus
    stats: LoopStats
    guard: PowerGuard
    telemetry_hz: float
    camera: CameraThread | None = None
    arbiter: Arbiter | None = None


@dataclass(frozen=True)
class LoopFacts:
    """What changes while the daemon runs and is not in a snapshot."""

    state: str
    bus_errors: int
    scheduling: str
    events_dropped: int


def status_message(src: StatusSources, snap: TickSnapshot | None, facts: LoopFacts) -> Status:
    cm = cm730_status(snap.cm730 if snap is not None else b"")
    alarms: list[AlarmInfo] = []
    if snap is not None:
        alarm = snap.alarm
        alarms = [{"id": j, "bits": int(alarm[j])} for j in src.robot.ids if alarm[j]]
    power, heat = src.guard.status()
    # The sub-maps are built as plain dicts and typed as the TypedDicts they are
    # (schemas/status_maps.py, documented key by key in docs/daemon.md).
    bus_info: dict[str, Any] = {
        **src.bus.status(),
        "bus_errors": facts.bus_errors,
        "arbiter": src.arbiter.counts if src.arbiter else {},
    }
    loop_info: dict[str, Any] = {
        **src.stats.summary(now=snap.time if snap is not None else None),
        "scheduling": facts.scheduling,
        "telemetry_hz": src.telemetry_hz,
        "events_dropped": facts.events_dropped,
    }
    return Status(
        state=facts.state,
        robot=src.name,
        lease=cast("LeaseInfo | None", src.lease.status()),
        motion=cast(MotionInfo, src.manager.status()),
        leds=cm["leds"],
        buttons=cm["buttons"],
        bus=cast(BusInfo, bus_info),
        loop=cast(LoopInfo, loop_info),
        voltage=cm["voltage"],
        alarms=alarms,
        network=src.network,
        version=PACKAGE_VERSION,
        power=power,
        heat=heat,
        protocol=list(src.protocol),
        camera=cast(CameraInfo, src.camera.status() if src.camera else dict(_NO_CAMERA)),
    )


def network_info(router: str | None, listen: list[str]) -> NetworkInfo:
    listen = list(listen)
    return NetworkInfo(
        endpoint=router or (listen[0] if listen else ""), router=router, listen=listen
    )


def as_payload(msg: Message) -> bytes:
    """``encode(msg)``'s bytes, by the compiled packer where it is built and takes every value
    (robot_daemon/hotpath.py; a status message through msgpack cost ~0.2 M instructions on the
    robot's Python, docs/loop-cpu.md), else by ``encode``."""
    if _compiled is not None:
        out = _compiled.packb(msg.to_dict())
        if out is not NotImplemented:
            return cast(bytes, out)
    return encode(msg)
