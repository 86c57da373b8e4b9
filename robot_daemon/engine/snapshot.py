"""One immutable snapshot per tick: what the tick read and wrote, in SI units, that every
message the daemon broadcasts is built from.

Taken once the goals are written, so joints, IMU and status of one tick agree with each other
(the same frame, the same servo health, the same goals), and none of them reads the bus's live
state, which the next tick overwrites. Plain tuples by joint id (slot 0 unused): the messages
want lists, and on 21 values one ``tolist`` costs less than any numpy operation.
``engine/broadcast.py`` builds the messages.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

from robot_daemon.hotpath import compiled as _compiled
from schemas import units

if TYPE_CHECKING:
    from robot_daemon.bus.robot_bus import RobotBus
    from robot_daemon.frames import JointFrame


class TickSnapshot(NamedTuple):
    """Immutable as a tuple is (a frozen dataclass's ``__init__`` sets each of its 19 fields
    through ``object.__setattr__``: ten times the cost, every tick)."""

    tick: int
    stamp: float  # s since the epoch, when the bus was read
    time: float  # s, the loop's clock at the tick's start
    position: list[float]  # rad, by joint id
    velocity: list[float]  # rad/s
    load: list[float]  # fraction of max torque, signed
    goal: list[float]  # rad: the goals the servos hold after this tick's write
    temperature: list[float]  # °C
    voltage: list[float]  # V
    torque: list[bool]
    online: list[bool]
    alarm: list[int]  # Dynamixel error bits of the last status packet
    gyro: list[float]  # rad/s, robot axes x y z
    accel: list[float]  # m/s²
    gyro_raw: list[int]  # counts
    accel_raw: list[int]
    cm730: bytes  # the CM-730's block as read (LEDs, buttons, voltage: cm730_status)
    cm730_online: bool
    fall: str  # the fall monitor's verdict on this frame ("none" without one)


_make: Any = tuple.__new__  # a TickSnapshot from its fields in order, as its __new__ does


def take(bus: RobotBus, frame: JointFrame, stamp: float, tick: int, fall: str) -> TickSnapshot:
    """The tick's snapshot (copies: the next tick writes the bus state's arrays): every list in
    one compiled call where it is built (the same lists, tests/unit/test_hotpath.py), else
    :func:`take_py`."""
    if _compiled is not None:
        st = bus.state
        sign, offset = bus.calibration.angle_columns
        lists = _compiled.snapshot_lists(
            (frame.position, frame.velocity, frame.load, st.temperature, st.voltage, st.torque,
             st.online, st.alarm, frame.gyro, frame.accel, frame.gyro_raw, frame.accel_raw),
            st.goal, sign, offset, units.RAD_PER_UNIT, units.POSITION_CENTER,
        )
        if lists is not NotImplemented:
            pos, vel, load, temp, volt, torque, online, alarm, gyro, accel, graw, araw, goal = lists
            online_cm = bus.cm730_online
            snap: TickSnapshot = _make(TickSnapshot, (
                tick, stamp, frame.time, pos, vel, load, goal, temp, volt, torque, online, alarm,
                gyro, accel, graw, araw, bus.cm730 if online_cm else b"", online_cm, fall,
            ))
            return snap
    return take_py(bus, frame, stamp, tick, fall)


def take_py(bus: RobotBus, frame: JointFrame, stamp: float, tick: int, fall: str) -> TickSnapshot:
    """:func:`take`'s definition: each array's ``tolist``."""
    st = bus.state
    return TickSnapshot(
        tick=tick,
        stamp=stamp,
        time=frame.time,
        position=frame.position.tolist(),
        velocity=frame.velocity.tolist(),
        load=frame.load.tolist(),
        goal=bus.calibration.positions_list(st.goal.tolist()),
        temperature=st.temperature.tolist(),
        voltage=st.voltage.tolist(),
        torque=st.torque.tolist(),
        online=st.online.tolist(),
        alarm=st.alarm.tolist(),
        gyro=frame.gyro.tolist(),
        accel=frame.accel.tolist(),
        gyro_raw=frame.gyro_raw.tolist(),
        accel_raw=frame.accel_raw.tolist(),
        cm730=bus.cm730 if bus.cm730_online else b"",
        cm730_online=bus.cm730_online,
        fall=fall,
    )
