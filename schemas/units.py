"""Unit conversions between the Dynamixel/CM-730 raw registers and SI, defined once.

Raw joint values are servo angles: raw 2048 is 0 rad, 4096 units per turn. Calibration offsets
and mounting directions from the robot config are applied by the bus layer around these.

numpy is imported only by what needs it (the lookup tables, made on first use): a program that
converts a few scalars (the gateway, the UIs, through the client) starts without it.
"""

from __future__ import annotations

import math
import sys
from typing import TYPE_CHECKING, Any, overload

if TYPE_CHECKING:
    import numpy as np

# MX-28 position: 0..4095, 2048 = 0 rad.
POSITION_CENTER = 2048
POSITION_MAX = 4095
UNITS_PER_REV = 4096
RAD_PER_UNIT = 2 * math.pi / UNITS_PER_REV
DEG_PER_UNIT = 360.0 / UNITS_PER_REV

# Speed registers (moving speed 32, present speed 38): 0.114 rpm per unit (e-manual).
RPM_PER_SPEED_UNIT = 0.114
RAD_S_PER_SPEED_UNIT = RPM_PER_SPEED_UNIT * 2 * math.pi / 60.0
# Moving speed 0 means "no limit": the MX-28's own maximum, about 55 rpm at 12 V.
MX28_MAX_RPM = 55.0
MX28_MAX_RAD_S = MX28_MAX_RPM * 2 * math.pi / 60.0
SPEED_MAX = 0x3FF  # the largest moving speed (10 bits)

# Present load (40): 0..1023 one way, 1024..2047 the other; ~0.1 % of max torque per unit.
LOAD_PERCENT_PER_UNIT = 0.1

# CM-730 IMU: 0..1023 centred on 512.
IMU_CENTER = 512
IMU_MAX = 1023
GRAVITY = 9.80665
ACCEL_G_PER_COUNT = 8.0 / IMU_MAX  # ±4 g full scale
# Gyro: ROBOTIS says ±500 °/s full scale; other sources ±1600 °/s. The config can override it.
GYRO_DPS_FULL_SCALE = 500.0


@overload
def raw_to_rad(raw: float) -> float: ...
@overload
def raw_to_rad(raw: np.ndarray) -> np.ndarray: ...
def raw_to_rad(raw: float | np.ndarray) -> float | np.ndarray:
    """Servo angle in rad for a raw position (scalar or array)."""
    return (raw - POSITION_CENTER) * RAD_PER_UNIT


def rad_to_raw(rad: float) -> int:
    """Nearest raw position for an angle; the caller checks the 0..4095 range."""
    return int(round(rad / RAD_PER_UNIT)) + POSITION_CENTER


def raw_to_deg(raw: int | float) -> float:
    return (raw - POSITION_CENTER) * DEG_PER_UNIT


def deg_to_raw(deg: float) -> int:
    return int(round(deg / DEG_PER_UNIT)) + POSITION_CENTER


def signed_11bit(raw: int | np.ndarray) -> int | np.ndarray:
    """Decode the MX-28's sign-magnitude speed/load words (bit 10 = direction); scalar or
    array."""
    magnitude = raw & 0x3FF
    numpy = sys.modules.get("numpy")  # an array exists only once numpy is imported
    if numpy is not None and isinstance(raw, numpy.ndarray):
        decoded: np.ndarray = numpy.where(raw & 0x400, -magnitude, magnitude)
        return decoded
    return -magnitude if raw & 0x400 else magnitude


def encode_signed_11bit(value: int) -> int:
    # Twice each step of each simulated servo (present speed and load): min(·, SPEED_MAX) as
    # the comparison it makes, without the builtin's call and iterator.
    magnitude = abs(int(value))
    if magnitude > SPEED_MAX:
        magnitude = SPEED_MAX
    return magnitude | (0x400 if value < 0 else 0)


def speed_raw_to_rad_s(raw: int | np.ndarray) -> float | np.ndarray:
    """Present speed register to rad/s (signed, CCW positive); scalar or array."""
    return signed_11bit(raw) * RAD_S_PER_SPEED_UNIT


def load_raw_to_fraction(raw: int | np.ndarray) -> float | np.ndarray:
    """Present load register to a signed fraction of max torque (-1..1); scalar or array."""
    return signed_11bit(raw) * LOAD_PERCENT_PER_UNIT / 100.0


# The two conversions above as tables over every 11-bit word, for the loop: one indexing of a
# table per tick instead of five array operations (index with ``raw & 0x7FF``). Made on first
# use (module ``__getattr__``) and then kept as ordinary module attributes, so the loop's
# ``units.SPEED_RAD_S_TABLE`` is a plain lookup.
_TABLES = {"SPEED_RAD_S_TABLE": speed_raw_to_rad_s, "LOAD_FRACTION_TABLE": load_raw_to_fraction}
if TYPE_CHECKING:
    SPEED_RAD_S_TABLE: np.ndarray
    LOAD_FRACTION_TABLE: np.ndarray


def __getattr__(name: str) -> Any:
    if name not in _TABLES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import numpy

    table = numpy.asarray(_TABLES[name](numpy.arange(0x800)))
    globals()[name] = table
    return table


def voltage_raw_to_v(raw: int) -> float:
    return raw / 10.0


def accel_raw_to_ms2(raw: int | float) -> float:
    return (raw - IMU_CENTER) * ACCEL_G_PER_COUNT * GRAVITY


def ms2_to_accel_raw(ms2: float) -> int:
    return int(round(ms2 / GRAVITY / ACCEL_G_PER_COUNT)) + IMU_CENTER


def gyro_raw_to_rad_s(raw: int | float, full_scale_dps: float = GYRO_DPS_FULL_SCALE) -> float:
    return (raw - IMU_CENTER) * (2 * full_scale_dps / IMU_MAX) * math.pi / 180.0


def rad_s_to_gyro_raw(rad_s: float, full_scale_dps: float = GYRO_DPS_FULL_SCALE) -> int:
    return int(round(rad_s * 180.0 / math.pi / (2 * full_scale_dps / IMU_MAX))) + IMU_CENTER


def rgb_to_color_word(r: int, g: int, b: int) -> int:
    """CM-730 15-bit LED colour: r>>3 in bits 0-4, g>>3 in 5-9, b>>3 in 10-14."""
    return ((r >> 3) & 0x1F) | (((g >> 3) & 0x1F) << 5) | (((b >> 3) & 0x1F) << 10)


def color_word_to_rgb(word: int) -> tuple[int, int, int]:
    return ((word & 0x1F) << 3, ((word >> 5) & 0x1F) << 3, ((word >> 10) & 0x1F) << 3)


# Return delay time (register 5): 2 µs per unit.
RETURN_DELAY_S_PER_UNIT = 2e-6


def return_delay_s(raw: int) -> float:
    return raw * RETURN_DELAY_S_PER_UNIT


def baud_register_to_bps(raw: int) -> int:
    """Baud rate register (4) to bits per second (Protocol 1.0: 2 Mbps / (raw + 1))."""
    return 2_000_000 // (raw + 1)


def wire_time_s(n_bytes: int, baud: int = 1_000_000) -> float:
    """Time ``n_bytes`` take on the wire at 8N1 (10 bits per byte)."""
    return n_bytes * 10.0 / baud
