"""Servo RAM a previous program may have left set, reset at start.

MOVING_SPEED and TORQUE_LIMIT are RAM: they survive a program restart while DXL power stays on
(RoboPlus leaves slow speeds behind), and a servo limited to a few rpm or a fifth of its torque
makes every motion wrong. As ROBOTIS's framework: ``MotionManager::SetEnable`` writes
MOVING_SPEED = 0 (no limit) to every servo (``Framework/src/MotionManager.cpp``), and the MX-28
loads TORQUE_LIMIT from MAX_TORQUE (EEPROM, address 14) at power-on (the MX-28 e-manual,
"Torque Limit"), which is what this writes back.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from robot_daemon.bus.dxl import DxlBus
from robot_daemon.bus.state import word
from robot_daemon.bus.tables import MX28

FULL_TORQUE = MX28.TORQUE_LIMIT.reg.high


def reset_servo_ram(
    bus: DxlBus, ids: Iterable[int], read: Callable[[int, int, int], bytes | None]
) -> dict[int, int]:
    """Write MOVING_SPEED = 0 and TORQUE_LIMIT = MAX_TORQUE on ``ids`` (one sync write);
    ``read(id, address, length)`` reads MAX_TORQUE (None: not read, full torque assumed).
    Returns id → the torque limit written."""
    limits: dict[int, int] = {}
    for jid in ids:
        data = read(jid, MX28.MAX_TORQUE.reg.address, 2)
        limits[jid] = min(FULL_TORQUE, word(data, 0)) if data else FULL_TORQUE
    if limits:
        # MOVING_SPEED (32, 2 bytes) and TORQUE_LIMIT (34, 2 bytes) are adjacent.
        rows = {j: bytes((0, 0, t & 0xFF, t >> 8)) for j, t in limits.items()}
        bus.sync_write(MX28.MOVING_SPEED.reg.address, 4, rows)
    return limits
