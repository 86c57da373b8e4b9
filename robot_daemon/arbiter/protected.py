"""Registers whose write can disable or lose hardware, as data keyed by the register tables.

A ``registers`` write touching any of these is refused unless the daemon runs with
``--allow-hardware-writes`` (config ``daemon.allow_hardware_writes``), which is distinct from
``--allow-eeprom`` (ordinary EEPROM such as alarm LEDs). Why each is here:

- power: CM-730 ``DXL_POWER`` = 0 cuts every servo's power (a walking robot collapses);
- identity and link: ``ID``, ``BAUD_RATE``, ``STATUS_RETURN_LEVEL``, ``RETURN_DELAY_TIME``: a
  changed value makes the device vanish from the bus the daemon expects;
- limits and protection: angle, voltage, temperature and torque limits, ``ALARM_SHUTDOWN``,
  ``LOCK`` (locks EEPROM until a power cycle), ``MULTI_TURN_OFFSET``/``RESOLUTION_DIVIDER``
  (change what a position means, so the calibration no longer holds).
"""

from __future__ import annotations

from enum import Enum

from robot_daemon.bus.tables import CM730, MX28

PROTECTED: frozenset[Enum] = frozenset(
    {
        CM730.DXL_POWER,
        CM730.ID,
        CM730.BAUD_RATE,
        CM730.RETURN_DELAY_TIME,
        CM730.STATUS_RETURN_LEVEL,
        MX28.ID,
        MX28.BAUD_RATE,
        MX28.RETURN_DELAY_TIME,
        MX28.STATUS_RETURN_LEVEL,
        MX28.CW_ANGLE_LIMIT,
        MX28.CCW_ANGLE_LIMIT,
        MX28.TEMPERATURE_LIMIT,
        MX28.MIN_VOLTAGE_LIMIT,
        MX28.MAX_VOLTAGE_LIMIT,
        MX28.MAX_TORQUE,
        MX28.TORQUE_LIMIT,
        MX28.ALARM_SHUTDOWN,
        MX28.MULTI_TURN_OFFSET,
        MX28.RESOLUTION_DIVIDER,
        MX28.LOCK,
    }
)


def is_protected(register: Enum) -> bool:
    return register in PROTECTED
