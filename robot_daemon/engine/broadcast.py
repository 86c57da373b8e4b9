"""The messages the daemon broadcasts: joints and IMU each tick, status at its rate.

Built from the bus state and the frame of a tick;
:class:`~robot_daemon.engine.publishers.Publishers` sends them off the motion thread.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from schemas.messages import Imu, Joints, Status
from schemas.status_maps import AlarmInfo, BusInfo, LeaseInfo, LoopInfo, MotionInfo, NetworkInfo
from schemas.versions import package_version

if TYPE_CHECKING:
    from config.loader import RobotConfig
    from robot_daemon.bus.robot_bus import RobotBus
    from robot_daemon.engine.daemon import Daemon
    from robot_daemon.frames import JointFrame
    from robot_daemon.motion.fall import FallMonitor


def joints_message(
    robot: RobotConfig, bus: RobotBus, frame: JointFrame, stamp: float, tick: int
) -> Joints:
    # Whole arrays, each taken once by the joint IDs (a slice when they run in a row, as the
    # DARwIn-OP's 1…20 do: cheaper than indexing by a list): this runs every tick.
    st = bus.state
    ids = robot.ids
    sel = _selection(ids)
    pos = frame.position[sel]
    return Joints(
        id=list(ids),
        name=list(robot.names),
        position=pos.tolist(),
        position_deg=np.degrees(pos).tolist(),
        goal=bus.calibration.positions(st.goal)[sel].tolist(),
        velocity=frame.velocity[sel].tolist(),
        load=frame.load[sel].tolist(),
        temperature=st.temperature[sel].astype(float).tolist(),
        voltage=st.voltage[sel].astype(float).tolist(),
        torque_enabled=st.torque[sel].astype(bool).tolist(),
        online=st.online[sel].astype(bool).tolist(),
        alarm=st.alarm[sel].astype(int).tolist(),
        stamp=stamp,
        tick=tick,
    )


@functools.lru_cache(maxsize=8)
def _selection(ids: tuple[int, ...]) -> slice | np.ndarray:
    if ids and ids == tuple(range(ids[0], ids[-1] + 1)):
        return slice(ids[0], ids[-1] + 1)
    return np.array(ids, dtype=int)


def imu_message(frame: JointFrame, fall: FallMonitor | None, stamp: float, tick: int) -> Imu:
    # The fall monitor (a motion module) classified this frame in manager.step.
    direction = fall.direction if fall is not None else "none"
    return Imu(
        gyro=[float(v) for v in frame.gyro],
        accel=[float(v) for v in frame.accel],
        gyro_raw=[int(v) for v in frame.gyro_raw],
        accel_raw=[int(v) for v in frame.accel_raw],
        fall=direction,
        stamp=stamp,
        tick=tick,
    )


def status_message(daemon: Daemon) -> Status:
    bus = daemon.bus
    cm = bus.cm730_status()
    st = bus.state
    alarms = [AlarmInfo(id=j, bits=int(st.alarm[j])) for j in daemon.robot.ids if st.alarm[j]]
    extra: dict[str, Any] = {}
    if daemon.camera is not None:
        extra["camera"] = daemon.camera.status()
    else:
        extra["camera"] = {"source": "none", "captured": 0, "subscribed": False, "capturing": False}
    # The parts build their maps as plain dicts; the casts name the key sets they promise
    # (schemas/status_maps.py, documented key by key in docs/daemon.md).
    bus_info: dict[str, Any] = {
        **bus.status(),
        "bus_errors": daemon.bus_errors,
        "arbiter": daemon.arbiter.counts if daemon.arbiter else {},
    }
    loop_info: dict[str, Any] = {
        **daemon.stats.summary(),
        "scheduling": daemon.scheduling,
        "telemetry_hz": daemon.telemetry.hz,
        "events_dropped": daemon.pub.dropped_events if daemon.pub is not None else 0,
    }
    return Status(
        state=str(daemon.state),
        robot=daemon.options.robot,
        lease=cast("LeaseInfo | None", daemon.lease.status()),
        motion=cast(MotionInfo, daemon.manager.status()),
        leds=cm["leds"],
        buttons=cm["buttons"],
        bus=cast(BusInfo, bus_info),
        loop=cast(LoopInfo, loop_info),
        voltage=cm["voltage"],
        alarms=alarms,
        network=network_info(daemon.options.router, daemon.options.listen),
        version=package_version(),
        power=daemon.guard.status()[0],
        heat=daemon.guard.status()[1],
        protocol=list(daemon.protocol),
        **extra,
    )


def network_info(router: str | None, listen: list[str]) -> NetworkInfo:
    listen = list(listen)
    return NetworkInfo(
        endpoint=router or (listen[0] if listen else ""), router=router, listen=listen
    )
