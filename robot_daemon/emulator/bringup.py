"""Emulator options for the behaviours of a real robot that a first session meets (issue 25),
each off by default so tests turn on the one they reproduce:

* ``old_firmware_ids``: servos reporting MX-28 firmware 26 (1024 positions per turn);
* ``leftover_ram_ids``: servos whose RAM a previous program left set while DXL power stayed on
  (RoboPlus leaves slow speeds): MOVING_SPEED ``LEFTOVER_SPEED`` and TORQUE_LIMIT
  ``LEFTOVER_TORQUE_LIMIT`` after every power-on, until the host writes them;
* ``sag_units``: the steady-state error of a P-only position loop under load, in position
  units at full external load with P = 32 (scaled by 32 / P): a loaded joint stands below its
  goal, so re-commanding the present position makes it sink by that much each time;
* ``cm730_late_reads`` (in :mod:`robot_daemon.emulator.servo_chain`): a CM-730 that answers late;
* DXL power lost: the ``dxl_power_loss`` control op (the CM-730's reset button, a glitch):
  DXL_POWER reads 0 and the servos go silent until the host powers them again.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robot_daemon.bus.tables import CM730, MX28

if TYPE_CHECKING:
    from robot_daemon.emulator.servo_chain import Bus
    from robot_daemon.emulator.settings import EmulatorSettings

OLD_FIRMWARE = 26
LEFTOVER_SPEED = 40  # ~4.6 rpm: a pose that takes seconds to reach
LEFTOVER_TORQUE_LIMIT = 200  # a fifth of the torque


def apply(bus: Bus, s: EmulatorSettings) -> None:
    for dxl_id in s.old_firmware_ids:
        bus.servo(dxl_id).firmware = OLD_FIRMWARE
    for dxl_id in s.leftover_ram_ids:
        bus.servo(dxl_id).leftover = {
            MX28.MOVING_SPEED: LEFTOVER_SPEED,
            MX28.TORQUE_LIMIT: LEFTOVER_TORQUE_LIMIT,
        }
    for servo in bus.servos.values():
        servo.sag_units = float(s.sag_units)
        servo.apply_overrides()


def dxl_power_loss(bus: Bus) -> None:
    """DXL power goes: the CM-730 reads DXL_POWER 0 and every servo is unpowered."""
    bus.cm730.table[CM730.DXL_POWER] = 0
    bus.cm730.on_power(False)
