"""Control tables of the CM-730 and the MX-28 (Dynamixel Protocol 1.0), as data.

One source for the emulator (layout, defaults, ranges, access) and the daemon (addresses).
Values from the ROBOTIS e-manual and the DARwIn-OP framework (CM730.h, MX28.h).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, IntEnum

BROADCAST_ID = 254
CM730_ID = 200
SERVO_IDS = tuple(range(1, 21))
MX28_MODEL = 29
CM730_MODEL = 0x7300


class Instruction(IntEnum):
    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    RESET = 0x06
    SYNC_WRITE = 0x83
    BULK_READ = 0x92


class ErrorBit(IntEnum):
    INPUT_VOLTAGE = 0x01
    ANGLE_LIMIT = 0x02
    OVERHEATING = 0x04
    RANGE = 0x08
    CHECKSUM = 0x10
    OVERLOAD = 0x20
    INSTRUCTION = 0x40


class Access(Enum):
    R = "r"
    RW = "rw"


@dataclass(frozen=True)
class Register:
    """One register of a control table: where it is, its size, access, default and range."""

    address: int
    size: int  # bytes, 1 or 2 (little-endian)
    access: Access
    default: int | None  # None: computed at run time (present values)
    low: int = 0
    high: int = 0xFFFF
    eeprom: bool = False

    @property
    def end(self) -> int:
        return self.address + self.size


def _rw(addr: int, size: int, default: int, low: int, high: int, eeprom: bool = False) -> Register:
    return Register(addr, size, Access.RW, default, low, high, eeprom)


def _r(addr: int, size: int, default: int | None = 0, eeprom: bool = False) -> Register:
    return Register(addr, size, Access.R, default, 0, 0xFFFF if size == 2 else 0xFF, eeprom)


class MX28(Enum):
    """MX-28 control table (Protocol 1.0 firmware)."""

    MODEL_NUMBER = _r(0, 2, MX28_MODEL, eeprom=True)
    FIRMWARE_VERSION = _r(2, 1, 30, eeprom=True)
    ID = _rw(3, 1, 1, 0, 253, eeprom=True)
    BAUD_RATE = _rw(4, 1, 1, 0, 254, eeprom=True)
    RETURN_DELAY_TIME = _rw(5, 1, 0, 0, 254, eeprom=True)
    CW_ANGLE_LIMIT = _rw(6, 2, 0, 0, 4095, eeprom=True)
    CCW_ANGLE_LIMIT = _rw(8, 2, 4095, 0, 4095, eeprom=True)
    TEMPERATURE_LIMIT = _rw(11, 1, 80, 0, 99, eeprom=True)
    MIN_VOLTAGE_LIMIT = _rw(12, 1, 60, 50, 160, eeprom=True)
    MAX_VOLTAGE_LIMIT = _rw(13, 1, 160, 50, 160, eeprom=True)
    MAX_TORQUE = _rw(14, 2, 1023, 0, 1023, eeprom=True)
    STATUS_RETURN_LEVEL = _rw(16, 1, 2, 0, 2, eeprom=True)
    ALARM_LED = _rw(17, 1, 36, 0, 127, eeprom=True)
    ALARM_SHUTDOWN = _rw(18, 1, 36, 0, 127, eeprom=True)
    MULTI_TURN_OFFSET = _rw(20, 2, 0, 0, 0xFFFF, eeprom=True)
    RESOLUTION_DIVIDER = _rw(22, 1, 1, 1, 4, eeprom=True)
    TORQUE_ENABLE = _rw(24, 1, 0, 0, 1)
    LED = _rw(25, 1, 0, 0, 1)
    D_GAIN = _rw(26, 1, 0, 0, 254)
    I_GAIN = _rw(27, 1, 0, 0, 254)
    P_GAIN = _rw(28, 1, 32, 0, 254)
    GOAL_POSITION = _rw(30, 2, 2048, 0, 4095)
    MOVING_SPEED = _rw(32, 2, 0, 0, 1023)
    TORQUE_LIMIT = _rw(34, 2, 1023, 0, 1023)
    PRESENT_POSITION = _r(36, 2, None)
    PRESENT_SPEED = _r(38, 2, None)
    PRESENT_LOAD = _r(40, 2, None)
    PRESENT_VOLTAGE = _r(42, 1, None)
    PRESENT_TEMPERATURE = _r(43, 1, None)
    REGISTERED = _r(44, 1, 0)
    MOVING = _r(46, 1, 0)
    LOCK = _rw(47, 1, 0, 0, 1)
    PUNCH = _rw(48, 2, 0, 0, 1023)
    GOAL_ACCELERATION = _rw(73, 1, 0, 0, 254)

    @property
    def reg(self) -> Register:
        return self.value


class CM730(Enum):
    """CM-730 sub-controller control table (ID 200)."""

    MODEL_NUMBER = _r(0, 2, CM730_MODEL, eeprom=True)
    FIRMWARE_VERSION = _r(2, 1, 0x13, eeprom=True)
    ID = _rw(3, 1, CM730_ID, 0, 253, eeprom=True)
    BAUD_RATE = _rw(4, 1, 1, 0, 254, eeprom=True)
    RETURN_DELAY_TIME = _rw(5, 1, 0, 0, 254, eeprom=True)
    STATUS_RETURN_LEVEL = _rw(16, 1, 2, 0, 2, eeprom=True)
    DXL_POWER = _rw(24, 1, 0, 0, 1)
    LED_PANEL = _rw(25, 1, 0, 0, 7)
    LED_HEAD = _rw(26, 2, 0, 0, 0x7FFF)
    LED_EYE = _rw(28, 2, 0, 0, 0x7FFF)
    BUTTON = _r(30, 1, 0)
    GYRO_Z = _r(38, 2, 512)
    GYRO_Y = _r(40, 2, 512)
    GYRO_X = _r(42, 2, 512)
    ACCEL_X = _r(44, 2, 512)
    ACCEL_Y = _r(46, 2, 512)
    ACCEL_Z = _r(48, 2, 512)
    VOLTAGE = _r(50, 1, 120)
    LEFT_MIC = _r(51, 2, 0)
    ADC2 = _r(53, 2, 0)
    ADC3 = _r(55, 2, 0)
    ADC4 = _r(57, 2, 0)
    ADC5 = _r(59, 2, 0)
    ADC6 = _r(61, 2, 0)
    ADC7 = _r(63, 2, 0)
    ADC8 = _r(65, 2, 0)
    RIGHT_MIC = _r(67, 2, 0)
    ADC10 = _r(69, 2, 0)
    ADC11 = _r(71, 2, 0)
    ADC12 = _r(73, 2, 0)
    ADC13 = _r(75, 2, 0)
    ADC14 = _r(77, 2, 0)
    ADC15 = _r(79, 2, 0)

    @property
    def reg(self) -> Register:
        return self.value


MX28_TABLE_SIZE = 74
CM730_TABLE_SIZE = 81

# What the daemon reads every tick: present position, speed, load of each servo, and the
# CM-730's sensor block from DXL_POWER (24) through the left microphone (51..52) and ADC2 (53).
SERVO_BULK_START = MX28.PRESENT_POSITION.reg.address
SERVO_BULK_LENGTH = 6
CM730_BULK_START = CM730.DXL_POWER.reg.address
CM730_BULK_LENGTH = 30


def sensor_blocks(
    servo_ids: tuple[int, ...] = SERVO_IDS, cm730_id: int = CM730_ID
) -> list[tuple[int, int, int]]:
    """The bulk read of a tick with every servo online, as (id, start, length) blocks: each
    servo's fast block, then the CM-730's sensors."""
    blocks = [(i, SERVO_BULK_START, SERVO_BULK_LENGTH) for i in servo_ids]
    return [*blocks, (cm730_id, CM730_BULK_START, CM730_BULK_LENGTH)]


# What the framework sync-writes every tick: D, I, P, reserved, goal L, goal H.
SYNC_WRITE_START = MX28.D_GAIN.reg.address
SYNC_WRITE_LENGTH = 6

# The CM-730's IMU registers for the robot axes (x forward, y left, z up), with their signs:
# register − 512 = sign · (the robot-axis quantity in counts). The real board's convention, as
# Webots' DARwIn-OP model mounts its devices (gyro X counts the rate about −forward, gyro Y
# about −left, gyro Z about +up; accel X the specific force along −left, Y along +forward, Z along
# +up) and feeds them to the unmodified ROBOTIS Walking.cpp (gyro X − 512 as its RL_GYRO, gyro
# Y − 512 as FB_GYRO) and Walk.cpp (accel Y below 512 − 80 = fallen forward). With the opposite
# gyro signs the framework's balance feedback is positive feedback and throws the gait over
# (physics.md; tests/physics pins it). The framework's fall rule (accel Y below centre = lying
# on its front) follows. The emulator writes body motion through this map and the daemon reads
# it back through it, so both always agree; the daemon publishes SI in robot axes.
IMU_GYRO_AXES: tuple[tuple[CM730, int], ...] = (
    (CM730.GYRO_X, -1),
    (CM730.GYRO_Y, -1),
    (CM730.GYRO_Z, 1),
)
IMU_ACCEL_AXES: tuple[tuple[CM730, int], ...] = (
    (CM730.ACCEL_Y, 1),
    (CM730.ACCEL_X, -1),
    (CM730.ACCEL_Z, 1),
)


# The rates a Dynamixel is tried at when nothing answers at the configured one: the MX-28's
# baud rate register values that a serial port sets without a custom divisor (the SDK's list):
# 1 M, 57,600 as shipped, then the rest (115,200 is register 16, 117,647 bps, 2 % off).
STANDARD_BAUDS = (1_000_000, 57_600, 115_200, 500_000, 2_000_000, 19_200, 9_600)
