"""The messages the daemon broadcasts: joints and IMU each tick, status at its rate.

Built from the bus state and the frame of a tick; :class:`~robot_daemon.publishers.Publishers`
sends them off the motion thread.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from schemas.messages import Imu, Joints, NetworkInfo, Status
from schemas.versions import package_version

if TYPE_CHECKING:
    from config.loader import RobotConfig
    from robot_daemon.bus.robot_bus import RobotBus
    from robot_daemon.daemon import Daemon
    from robot_daemon.frames import JointFrame
    from robot_daemon.motion.fall import FallMonitor


def joints_message(
    robot: RobotConfig, bus: RobotBus, frame: JointFrame, stamp: float, tick: int
) -> Joints:
    # Whole arrays, indexed once by the joint IDs: this runs every tick.
    st = bus.state
    ids = robot.ids
    idx = list(ids)
    pos = frame.position[idx]
    return Joints(
        id=idx,
        name=list(robot.names),
        position=pos.tolist(),
        position_deg=np.degrees(pos).tolist(),
        goal=bus.calibration.positions(st.goal)[idx].tolist(),
        velocity=frame.velocity[idx].tolist(),
        load=frame.load[idx].tolist(),
        temperature=st.temperature[idx].astype(float).tolist(),
        voltage=st.voltage[idx].astype(float).tolist(),
        torque_enabled=st.torque[idx].astype(bool).tolist(),
        online=st.online[idx].astype(bool).tolist(),
        alarm=st.alarm[idx].astype(int).tolist(),
        stamp=stamp,
        tick=tick,
    )


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
    alarms = [{"id": j, "bits": int(st.alarm[j])} for j in daemon.robot.ids if st.alarm[j]]
    extra: dict[str, Any] = {}
    if daemon.camera is not None:
        extra["camera"] = daemon.camera.status()
    else:
        extra["camera"] = {"source": "none", "captured": 0, "subscribed": False}
    return Status(
        state=str(daemon.state),
        robot=daemon.options.robot,
        lease=daemon.lease.status(),
        motion=daemon.manager.status(),
        leds=cm["leds"],
        buttons=cm["buttons"],
        bus={
            **bus.status(),
            "bus_errors": daemon.bus_errors,
            "arbiter": daemon.arbiter.counts if daemon.arbiter else {},
        },
        loop={
            **daemon.stats.summary(),
            "scheduling": daemon.scheduling,
            "events_dropped": daemon.pub.dropped_events if daemon.pub is not None else 0,
        },
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
