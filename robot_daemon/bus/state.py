"""What the daemon knows of the devices between ticks: raw servo state, the CM-730's sensor
block decoded, and the bus counters published in ``status.bus``."""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field
from operator import itemgetter
from typing import Any

import numpy as np

from robot_daemon.bus.tables import (
    CM730,
    CM730_BULK_START,
    IMU_ACCEL_AXES,
    IMU_GYRO_AXES,
    Register,
)
from robot_daemon.frames import N_SLOTS
from robot_daemon.hotpath import compiled as _compiled
from schemas import units


def _centred() -> np.ndarray:
    return np.full(N_SLOTS, units.POSITION_CENTER, dtype=int)


def word(data: bytes, offset: int) -> int:
    return data[offset] | (data[offset + 1] << 8)


def field_value(block: bytes, start: int, reg: Register) -> int:
    """A register's value out of a block read from address ``start``."""
    off = reg.address - start
    return word(block, off) if reg.size == 2 else block[off]


@dataclass
class BusCounters:
    """Counts of what happened on the bus since the daemon started (published in ``status``)."""

    bulk_reads: int = 0
    missing_replies: int = 0
    corrupt_replies: int = 0
    retries: int = 0
    stale_ticks: int = 0
    bus_stalls: int = 0  # ticks where nothing answered at all (not counted against servos)
    sync_writes: int = 0
    goal_writes: int = 0
    skipped_goals: int = 0  # goals not written: joint offline or torque off
    limit_clamps: int = 0
    port_reopens: int = 0

    def to_dict(self) -> dict[str, int]:
        return dict(vars(self))


@dataclass
class ServoState:
    """Last known raw state of every joint, by id (slot 0 unused)."""

    position: np.ndarray = field(default_factory=_centred)
    speed: np.ndarray = field(default_factory=lambda: np.zeros(N_SLOTS, dtype=int))
    load: np.ndarray = field(default_factory=lambda: np.zeros(N_SLOTS, dtype=int))
    temperature: np.ndarray = field(default_factory=lambda: np.zeros(N_SLOTS))
    voltage: np.ndarray = field(default_factory=lambda: np.zeros(N_SLOTS))
    torque: np.ndarray = field(default_factory=lambda: np.zeros(N_SLOTS, dtype=bool))
    online: np.ndarray = field(default_factory=lambda: np.zeros(N_SLOTS, dtype=bool))
    misses: np.ndarray = field(default_factory=lambda: np.zeros(N_SLOTS, dtype=int))
    alarm: np.ndarray = field(default_factory=lambda: np.zeros(N_SLOTS, dtype=int))
    goal: np.ndarray = field(default_factory=_centred)
    # TORQUE_LIMIT as last read: 0 after an alarm shutdown (the servo is limp though
    # TORQUE_ENABLE reads 1), so ``torque`` is enable *and* a limit above 0.
    torque_limit: np.ndarray = field(default_factory=lambda: np.full(N_SLOTS, 1023, dtype=int))
    firmware: dict[int, int] = field(default_factory=dict)


def cm730_field(block: bytes, reg: CM730) -> int:
    """A register out of the CM-730's bulk-read block (30 bytes from ``CM730_BULK_START``)."""
    return field_value(block, CM730_BULK_START, reg.reg)


# The IMU's six words are one run of the CM-730's bulk-read block (GYRO_Z … ACCEL_Z), read
# with one unpack; each axis's word in it, in robot axes (x, y, z), picked in one call.
_GYRO_AT = tuple(reg.reg.address - CM730_BULK_START for reg, _ in IMU_GYRO_AXES)
_ACCEL_AT = tuple(reg.reg.address - CM730_BULK_START for reg, _ in IMU_ACCEL_AXES)
_IMU_FIRST = min(_GYRO_AT + _ACCEL_AT)
_IMU_WORDS = struct.Struct(f"<{(max(_GYRO_AT + _ACCEL_AT) - _IMU_FIRST) // 2 + 1}H")
_GYRO_PICK = itemgetter(*((o - _IMU_FIRST) // 2 for o in _GYRO_AT))
_ACCEL_PICK = itemgetter(*((o - _IMU_FIRST) // 2 for o in _ACCEL_AT))
_GYRO_SIGN = tuple(s for _, s in IMU_GYRO_AXES)
_ACCEL_SIGN = tuple(s for _, s in IMU_ACCEL_AXES)


def imu_raw(block: bytes) -> tuple[list[int], list[int]]:
    """Gyro and accelerometer counts in robot axes (x, y, z)."""
    if not block:
        return [units.IMU_CENTER] * 3, [units.IMU_CENTER] * 3
    words = _IMU_WORDS.unpack_from(block, _IMU_FIRST)
    return list(_GYRO_PICK(words)), list(_ACCEL_PICK(words))


_IMU_NEED = _IMU_FIRST + _IMU_WORDS.size  # imu_raw's unpack reads this much of the block
# Each axis's word's byte offset in the block, as imu_raw picks them out of its unpack.
_GYRO_BYTES = tuple(_IMU_FIRST + 2 * i for i in _GYRO_PICK(range(_IMU_WORDS.size // 2)))
_ACCEL_BYTES = tuple(_IMU_FIRST + 2 * i for i in _ACCEL_PICK(range(_IMU_WORDS.size // 2)))


def imu_arrays(
    block: bytes, gyro_dps: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The frame's IMU arrays: gyro and accelerometer counts and SI values in robot axes
    (x, y, z), by one compiled call into four arrays made empty where it is built (the same
    values, tests/unit/test_hotpath.py), else :func:`imu_arrays_py`, their definition."""
    if _compiled is not None and block:
        out = (np.empty(3, int), np.empty(3, int), np.empty(3), np.empty(3))
        if _compiled.imu_arrays(block, _IMU_NEED, _GYRO_BYTES, _ACCEL_BYTES, _GYRO_SIGN,
                                _ACCEL_SIGN, units.IMU_CENTER, 2 * gyro_dps / units.IMU_MAX,
                                math.pi, units.ACCEL_G_PER_COUNT, units.GRAVITY, *out) is True:
            return out
    return imu_arrays_py(block, gyro_dps)


def imu_arrays_py(
    block: bytes, gyro_dps: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`imu_arrays`' definition: :func:`imu_raw`'s counts and :func:`imu_si`'s values."""
    gyro_raw, accel_raw = imu_raw(block)
    gyro, accel = imu_si(gyro_raw, accel_raw, gyro_dps)
    return np.array(gyro_raw), np.array(accel_raw), gyro, accel


def imu_si(
    gyro_raw: list[int], accel_raw: list[int], gyro_dps: float
) -> tuple[np.ndarray, np.ndarray]:
    """Gyro (rad/s) and accelerometer (m/s²) in robot axes from :func:`imu_raw`'s counts:
    ``units.gyro_raw_to_rad_s`` and ``units.accel_raw_to_ms2`` written out in their own order
    of operations (the same bits; six Python calls a tick fewer)."""
    f = 2 * gyro_dps / units.IMU_MAX
    lists: Any = NotImplemented
    if _compiled is not None:  # the same bits (tests/unit/test_hotpath.py)
        lists = _compiled.imu_lists(gyro_raw, accel_raw, _GYRO_SIGN, _ACCEL_SIGN,
                                    units.IMU_CENTER, f, math.pi, units.ACCEL_G_PER_COUNT,
                                    units.GRAVITY)
    gyro, accel = imu_lists_py(gyro_raw, accel_raw, f) if lists is NotImplemented else lists
    return np.array(gyro), np.array(accel)


def imu_lists_py(gyro_raw: list[int], accel_raw: list[int], f: float
                 ) -> tuple[list[float], list[float]]:
    """:func:`imu_si`'s arithmetic (``f``: rad/s-per-count before the degrees' π/180), the
    definition of what ``robot_daemon/_hotpath.c``'s ``imu_lists`` computes."""
    c, pi = units.IMU_CENTER, math.pi
    a, g = units.ACCEL_G_PER_COUNT, units.GRAVITY
    gyro = [s * ((r - c) * f * pi / 180.0) for r, s in zip(gyro_raw, _GYRO_SIGN, strict=True)]
    accel = [s * ((r - c) * a * g) for r, s in zip(accel_raw, _ACCEL_SIGN, strict=True)]
    return gyro, accel


# The fields status reports, each one's (offset, size) in the block looked up once: an enum
# member's register looked up per field was most of cm730_status's cost.
_STATUS_FIELDS = tuple(
    (reg.reg.address - CM730_BULK_START, reg.reg.size)
    for reg in (CM730.BUTTON, CM730.LED_HEAD, CM730.LED_EYE, CM730.LED_PANEL, CM730.VOLTAGE,
                CM730.DXL_POWER)
)


def cm730_status(block: bytes) -> dict[str, Any]:
    """LEDs, buttons, voltage and power from the block; empty before the CM-730 answered."""
    if not block or not any(block):
        return {"leds": {}, "buttons": {}, "voltage": 0.0}
    buttons, head, eye, panel, voltage, power = (
        word(block, off) if size == 2 else block[off] for off, size in _STATUS_FIELDS
    )
    return {
        "leds": {
            "head": list(units.color_word_to_rgb(head)),
            "eye": list(units.color_word_to_rgb(eye)),
            "panel": panel,
        },
        "buttons": {"mode": bool(buttons & 1), "start": bool(buttons & 2)},
        "voltage": units.voltage_raw_to_v(voltage),
        "power": bool(power),
    }
