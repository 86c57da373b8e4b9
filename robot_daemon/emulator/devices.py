"""The simulated devices: an MX-28 servo (with its dynamics) and the CM-730 (with its IMU).

Each device owns a :class:`ControlTable`; the bus engine calls :meth:`Device.read` and
:meth:`Device.write`, the emulator calls :meth:`Servo.step` to move time on.

Modelling choices (documented, not firmware-exact):

* The plant: by default (kinematic) a servo with torque on moves its present position toward the
  goal at the moving speed (0 = the MX-28's maximum, 55 rpm at 12 V, scaled with the supply
  voltage); torque off leaves it where it is (the world may move it with
  :meth:`Servo.set_position`). Under a physics plant (``robot_daemon/plant/physics``) the plant
  reads the registers (goal, gains, torque limit, torque enable) and reports the joint back
  through :meth:`Servo.plant_update`: position, speed and the motor's torque.
* Present load is the external load the world applies plus a share for accelerating the horn
  (kinematic), or the motor's torque over the stall torque at the present voltage (physics: the
  MX-28's load is its output duty); at or over the torque limit it raises OVERLOAD, so a full
  external load fires it at the default limit (1023) too. Under physics a motor held at its
  torque limit for ``OVERLOAD_AFTER_S`` raises OVERLOAD too (the firmware's "the load cannot
  be controlled with the set maximum torque"). OVERLOAD is latched: it stays in every status
  packet until the host writes a non-zero TORQUE_LIMIT with the load gone (a re-arm with the
  load still there latches it again at once, as ROBOTIS's Q&A reports of the MX-28).
* Temperature follows a first-order model: it settles at ``ambient + heat_gain · load²`` with
  time constant ``thermal_tau_s``. Above the temperature limit OVERHEATING is raised, and it
  stays until the servo has cooled ``OVERHEAT_HYSTERESIS_C`` below the limit.
* An alarm whose bit is in ALARM_SHUTDOWN sets TORQUE_LIMIT to 0: the servo goes limp while
  TORQUE_ENABLE still reads 1, and stays limp until the host writes a non-zero TORQUE_LIMIT
  (the MX-28 e-manual, Protocol 1.0 control table, "Torque Limit (34)": "If the function of
  Alarm Shutdown is triggered, the motor loses its torque because the value becomes 0. At this
  moment, if the value is changed to the value other than 0, the motor can be used again";
  https://emanual.robotis.com/docs/en/dxl/mx/mx-28/). While the alarm stands the limit is put
  back to 0 at once.
* Power-up (CM-730 DXL_POWER 0 → 1) restores the RAM area, with the goal at the present position.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robot_daemon.bus.tables import (
    CM730,
    CM730_TABLE_SIZE,
    IMU_ACCEL_AXES,
    IMU_GYRO_AXES,
    MX28,
    MX28_TABLE_SIZE,
    ErrorBit,
)
from robot_daemon.emulator.control_table import ControlTable
from schemas import units

# The addresses Servo._sync_registers writes in place (sizes checked here, once).
_PRESENT_POSITION = MX28.PRESENT_POSITION.value.address
_PRESENT_SPEED = MX28.PRESENT_SPEED.value.address
_PRESENT_LOAD = MX28.PRESENT_LOAD.value.address
_PRESENT_VOLTAGE = MX28.PRESENT_VOLTAGE.value.address
_PRESENT_TEMPERATURE = MX28.PRESENT_TEMPERATURE.value.address
_MOVING = MX28.MOVING.value.address
_GOAL_POSITION = MX28.GOAL_POSITION.value.address
_TORQUE_ENABLE = MX28.TORQUE_ENABLE.value.address
_TORQUE_LIMIT = MX28.TORQUE_LIMIT.value.address
# And those every status packet reads (its alarms), and the reply settings, which the CM-730
# keeps at the servos' addresses.
_MIN_VOLTAGE_LIMIT = MX28.MIN_VOLTAGE_LIMIT.value.address
_MAX_VOLTAGE_LIMIT = MX28.MAX_VOLTAGE_LIMIT.value.address
_TEMPERATURE_LIMIT = MX28.TEMPERATURE_LIMIT.value.address
_TORQUE_LIMIT_HIGH = MX28.TORQUE_LIMIT.value.high
_ALARM_SHUTDOWN = MX28.ALARM_SHUTDOWN.value.address
# And those a step and a goal's write read (the bytes, not the items: an enum member's
# attribute and the table's item access are each a few Python calls).
_MOVING_SPEED = MX28.MOVING_SPEED.value.address
_P_GAIN = MX28.P_GAIN.value.address
_CW_ANGLE_LIMIT = MX28.CW_ANGLE_LIMIT.value.address
_CCW_ANGLE_LIMIT = MX28.CCW_ANGLE_LIMIT.value.address
_LOCK = MX28.LOCK.value.address
_GOAL_REGISTER = MX28.GOAL_POSITION.value
_TORQUE_LIMIT_REGISTER = MX28.TORQUE_LIMIT.value
_ID = MX28.ID.value.address
_RETURN_DELAY_TIME = MX28.RETURN_DELAY_TIME.value.address
_STATUS_RETURN_LEVEL = MX28.STATUS_RETURN_LEVEL.value.address
assert tuple(
    r.value.address for r in (CM730.ID, CM730.RETURN_DELAY_TIME, CM730.STATUS_RETURN_LEVEL)
) == (_ID, _RETURN_DELAY_TIME, _STATUS_RETURN_LEVEL)
_TWO_BYTES = (
    MX28.PRESENT_POSITION,
    MX28.PRESENT_SPEED,
    MX28.PRESENT_LOAD,
    MX28.GOAL_POSITION,
    MX28.MOVING_SPEED,
    MX28.CW_ANGLE_LIMIT,
    MX28.CCW_ANGLE_LIMIT,
)
_ONE_BYTE = (
    MX28.P_GAIN,
    MX28.LOCK,
    MX28.PRESENT_VOLTAGE,
    MX28.PRESENT_TEMPERATURE,
    MX28.MOVING,
    MX28.TORQUE_ENABLE,
    MX28.MIN_VOLTAGE_LIMIT,
    MX28.MAX_VOLTAGE_LIMIT,
    MX28.TEMPERATURE_LIMIT,
    MX28.ALARM_SHUTDOWN,
    MX28.ID,
    MX28.RETURN_DELAY_TIME,
    MX28.STATUS_RETURN_LEVEL,
    CM730.ID,
    CM730.RETURN_DELAY_TIME,
    CM730.STATUS_RETURN_LEVEL,
)
assert all(r.value.size == 2 for r in (*_TWO_BYTES, MX28.TORQUE_LIMIT))
assert all(r.value.size == 1 for r in _ONE_BYTE)

# What _sync_registers and _load compute with (units' own values, bound once).
_UNITS_PER_REV = units.UNITS_PER_REV
_RPM_PER_SPEED_UNIT = units.RPM_PER_SPEED_UNIT
_LOAD_PERCENT_PER_UNIT = units.LOAD_PERCENT_PER_UNIT
_encode_signed_11bit = units.encode_signed_11bit  # present speed and load: 10 bits and a sign
_TOP_SPEED = units.MX28_MAX_RPM * units.UNITS_PER_REV / 60.0
_MAX_RPM = units.MX28_MAX_RPM
_POSITION_MAX = float(units.POSITION_MAX)

# The CM-730's registers its refresh writes in place (the IMU's are two bytes each).
_CM730_VOLTAGE = CM730.VOLTAGE.value.address
assert CM730.VOLTAGE.value.size == 1
assert all(m.value.size == 2 for m, _ in (*IMU_GYRO_AXES, *IMU_ACCEL_AXES))
_IMU_MAX = units.IMU_MAX
# The overheating alarm, once raised, lasts until the servo is this much below its limit.
OVERHEAT_HYSTERESIS_C = 5.0
# Under a physics plant, a motor saturated at its torque limit this long raises OVERLOAD (s).
OVERLOAD_AFTER_S = 1.0
# MX-28 stall torque at 12 V (N·m, ROBOTIS e-manual); the physics plant's load is relative to it.
STALL_TORQUE_12V = 2.5


@dataclass
class Environment:
    """What every device shares: the supply voltage and the room."""

    voltage: float = 12.0
    ambient_c: float = 35.0
    heat_gain_c: float = 70.0
    thermal_tau_s: float = 60.0


class Device:
    # The address of the EEPROM lock register (one byte), on devices that have one.
    lock_address: int | None = None

    def __init__(self, table: ControlTable, env: Environment) -> None:
        self.table = table
        # MX28 or CM730, which both have ID and the reply settings.
        self.regs: type[MX28] | type[CM730] = table.kind  # type: ignore[assignment]
        self.env = env

    # Read for every status packet (21 a bulk read, 125 bulk reads a second): the byte at its
    # address, the same value the table's item access decodes.
    @property
    def id(self) -> int:
        return self.table.data[_ID]

    @property
    def status_return_level(self) -> int:
        return self.table.data[_STATUS_RETURN_LEVEL]

    @property
    def return_delay_s(self) -> float:
        return units.return_delay_s(self.table.data[_RETURN_DELAY_TIME])

    def alarm_bits(self) -> int:
        """Standing error bits every status packet of this device carries."""
        return 0

    def read_key(self) -> tuple[object, ...] | None:
        """Everything a read of this device depends on, when a read changes nothing (then two
        reads with equal keys give equal bytes and error bits); None when that is not known."""
        return None

    def refresh(self) -> None:
        """Bring computed registers up to date before a read."""

    def read(self, address: int, length: int) -> tuple[bytes, int]:
        self.refresh()
        data, err = self.table.read(address, length)
        return data, err | self.alarm_bits()

    def write(self, address: int, data: bytes) -> int:
        lock = self.lock_address
        locked = lock is not None and self.table.data[lock] != 0
        changes, err = self.table.check_write(address, data, locked)
        err |= self.check_values(changes)
        if err:
            return err | self.alarm_bits()
        for reg, value in changes:
            self.table.put(reg, value)
        return self.after_write([reg for reg, _ in changes])

    def check_values(self, changes: list) -> int:
        return 0

    def after_write(self, changed: list) -> int:
        """What a write does beyond its registers; the alarm bits its status packet carries."""
        return self.alarm_bits()

    def factory_reset(self) -> None:
        """RESET: every default back, except the ID, so the simulated bus stays addressable."""
        keep = self.id
        self.table.reset()
        self.table[self.regs.ID] = keep


class Servo(Device):
    lock_address = _LOCK

    def __init__(
        self, dxl_id: int, env: Environment, position: int = units.POSITION_CENTER
    ) -> None:
        super().__init__(ControlTable(MX28, MX28_TABLE_SIZE), env)
        self.table[MX28.ID] = dxl_id
        self.position = float(position)  # raw units, kept fractional between steps
        self.velocity = 0.0  # raw units per second
        self.temperature = env.ambient_c
        self.external_load = 0.0  # fraction of max torque the world applies, signed
        self.forced_temperature: float | None = None
        self.overheated = False
        self.overload_latched = False  # OVERLOAD stays until a re-arm (TORQUE_LIMIT written)
        self.powered = False
        # Set by a physics plant (plant_update): the motor's torque (N·m); None = kinematic plant.
        self.plant_torque: float | None = None
        self.saturated_s = 0.0  # how long the physics motor has been held at its limit
        # Options of robot_daemon/emulator/bringup.py: firmware version, RAM left by a previous
        # program (set again at every power-on), steady-state error under load.
        self.firmware: int | None = None
        self.leftover: dict = {}
        self.sag_units = 0.0
        self._at_rest: tuple[bytes, tuple[object, ...]] | None = None  # left by its last step
        self._sync_registers()

    def apply_overrides(self) -> None:
        if self.firmware is not None:
            self.table[MX28.FIRMWARE_VERSION] = self.firmware
        for reg, value in self.leftover.items():
            self.table[reg] = value

    # ---- alarms -----------------------------------------------------------------------------

    def alarm_bits(self) -> int:
        d = self.table.data  # every status packet: the bytes, not the items
        bits = 0
        v10 = self.env.voltage * 10
        if not d[_MIN_VOLTAGE_LIMIT] <= v10 <= d[_MAX_VOLTAGE_LIMIT]:
            bits |= ErrorBit.INPUT_VOLTAGE
        limit = d[_TEMPERATURE_LIMIT]
        if self.temperature > limit:
            self.overheated = True
        elif self.temperature < limit - OVERHEAT_HYSTERESIS_C:
            self.overheated = False
        if self.overheated:
            bits |= ErrorBit.OVERHEATING
        # Latched: nothing to look at. Kinematic with no load from the world (nearly every
        # read): nothing to find.
        if (
            not self.overload_latched
            and (self.plant_torque is not None or self.external_load)
            and self._overloaded()
        ):
            self.overload_latched = True
        if self.overload_latched:
            bits |= ErrorBit.OVERLOAD
        return bits

    def _overloaded(self) -> bool:
        if not self.drives():
            return False
        if self.plant_torque is None:  # kinematic: the world's load against the limit
            load = abs(self.external_load) * _TORQUE_LIMIT_HIGH
            if load <= 0:
                return False
            d = self.table.data
            return load >= d[_TORQUE_LIMIT] | (d[_TORQUE_LIMIT + 1] << 8)
        # physics: the motor cannot exceed its limit, it stays saturated at it
        return self.saturated_s >= OVERLOAD_AFTER_S

    def _shut_down_if_alarmed(self) -> int:
        """The alarm shutdown: torque limit 0 while an alarm in ALARM_SHUTDOWN stands. Returns
        the alarm bits, which the shutdown leaves as they are (it clears nothing, and a limp
        motor raises nothing): what a status packet read right after it carries."""
        bits = self.alarm_bits()
        d = self.table.data
        if bits & d[_ALARM_SHUTDOWN]:
            d[_TORQUE_LIMIT] = d[_TORQUE_LIMIT + 1] = 0
        return bits

    # ---- writes -----------------------------------------------------------------------------
    # Every goal the daemon sends passes here (20 a tick while it moves). A register is one
    # object, the table's own: compared by identity, not by the dataclass's field-by-field
    # ``__eq__`` (Python code, once for each register of the write).

    def check_values(self, changes: list) -> int:
        for reg, value in changes:
            if reg is _GOAL_REGISTER:
                d = self.table.data
                cw = d[_CW_ANGLE_LIMIT] | (d[_CW_ANGLE_LIMIT + 1] << 8)
                ccw = d[_CCW_ANGLE_LIMIT] | (d[_CCW_ANGLE_LIMIT + 1] << 8)
                if (cw or ccw) and not cw <= value <= ccw:
                    return ErrorBit.ANGLE_LIMIT
        return 0

    def after_write(self, changed: list) -> int:
        for reg in changed:
            if reg is _TORQUE_LIMIT_REGISTER:
                d = self.table.data
                if d[_TORQUE_LIMIT] or d[_TORQUE_LIMIT + 1]:
                    # A re-arm: the overload alarm goes if its cause has (else it latches
                    # again below).
                    self.overload_latched = False
        return self._shut_down_if_alarmed()

    # ---- power and dynamics -----------------------------------------------------------------

    def power(self, on: bool) -> None:
        if on and not self.powered:
            self.overload_latched = False  # a power cycle clears every alarm
            self.table.reset(eeprom=False)
            self.table[MX28.GOAL_POSITION] = round(self.position)
            for reg, value in self.leftover.items():
                self.table[reg] = value
        self.powered = on
        if not on:
            self.velocity = 0.0
        self._sync_registers()

    def max_speed(self) -> float:
        """Speed limit in raw units per second for the current moving speed register."""
        # (Each step of a servo that moves: min and max written as the comparisons they make,
        # max(a, b) = b if b > a else a, without the builtins' call and iterator each.)
        volts = self.env.voltage
        top = _MAX_RPM * (0.0 if volts < 0.0 else volts) / 12.0
        d = self.table.data
        rpm = (d[_MOVING_SPEED] | (d[_MOVING_SPEED + 1] << 8)) * _RPM_PER_SPEED_UNIT
        rpm = top if rpm == 0 or top < rpm else rpm
        return rpm * _UNITS_PER_REV / 60.0

    def drives(self) -> bool:
        """The motor holds its goal: powered, torque enabled and a torque limit above 0."""
        d = self.table.data  # several times a step: the bytes, not the items
        return (
            self.powered
            and d[_TORQUE_ENABLE] != 0
            and (d[_TORQUE_LIMIT] != 0 or d[_TORQUE_LIMIT + 1] != 0)
        )

    def load_fraction(self) -> float:
        return self._load(self.drives())

    def _load(self, drives: bool) -> float:
        """:meth:`load_fraction`, for a caller that knows already whether the motor drives."""
        if not drives:
            return 0.0
        torque = self.plant_torque
        if torque is not None:
            volts = self.env.voltage  # max(volts, 1e-3), and below min and max: see max_speed
            load = torque / (STALL_TORQUE_12V * (1e-3 if volts < 1e-3 else volts) / 12.0)
        else:
            load = self.external_load + 0.15 * self.velocity / _TOP_SPEED
        load = load if load < 1.0 else 1.0
        return load if load > -1.0 else -1.0

    def _rest_state(self) -> tuple[object, ...]:
        """What a step reads of the servo besides its registers (each servo's, at each step
        and each bulk read)."""
        env = self.env
        return (
            self.velocity,
            self.plant_torque,
            self.forced_temperature,
            self.external_load,
            self.temperature,
            env.ambient_c,
            self.powered,
            self.position,
            env.voltage,
            self.overheated,
            self.overload_latched,
        )

    def _rest_key(self) -> tuple[bytes, tuple[object, ...]] | None:
        """What a servo at rest depends on (None: it is not at rest). At rest, a step computes
        exactly what it holds: it moved nothing (at its goal, or no speed to move with), it has
        no load and it is at the ambient temperature, the only one a step cannot change."""
        if not (
            self.velocity == 0.0
            and self.plant_torque is None
            and self.forced_temperature is None
            and self.external_load == 0.0
            and self.temperature == self.env.ambient_c
        ):
            return None
        # Every register, however it was written since.
        return bytes(self.table.data), self._rest_state()

    def read_key(self) -> tuple[object, ...] | None:
        # At rest a read's inputs are all in the rest key: the registers (the present values
        # synced into them included), power, supply, the alarms' latches; no load, no plant
        # torque and the ambient temperature leave nothing else for the alarms to look at.
        # While nothing in it has changed, the key the last step left: the same object each
        # bulk read, which Bus._bulk_reply finds its reply by at once, and which the next
        # step finds unchanged (the same test as a new key's, without copying the registers).
        rest = self._at_rest
        if rest is not None and self.table.data == rest[0] and self._rest_state() == rest[1]:
            return rest
        return self._rest_key()

    def step(self, dt: float) -> None:
        # The emulator steps every servo before each packet it answers and at each physics
        # round, and most servos stand still: one that was at rest after its last step, with
        # nothing changed since, is skipped (the step would write the same bytes).
        # (read_key's test of the key, without making a new one when it fails.)
        rest = self._at_rest
        if dt <= 0 or (
            rest is not None and self.table.data == rest[0] and self._rest_state() == rest[1]
        ):
            return
        self._full_step(dt)
        self._at_rest = self._rest_key()

    def _full_step(self, dt: float) -> None:
        # Whether the motor drives, and its load, found once: a step changes neither until
        # its alarm shutdown, after which they are found again.
        d = self.table.data
        drives = self.drives()
        if self.plant_torque is not None:
            pass  # the physics plant moved the horn (plant_update)
        elif drives:
            goal = float(d[_GOAL_POSITION] | (d[_GOAL_POSITION + 1] << 8))
            if self.sag_units:
                # A P-only loop stands off its goal in proportion to the load over the gain.
                goal -= self.sag_units * self.external_load * 32.0 / max(1, d[_P_GAIN])
            limit = self.max_speed() * dt
            # The clamps min and max would make (see max_speed).
            move = goal - self.position
            move = move if move < limit else limit
            move = move if move > -limit else -limit
            position = self.position + move
            position = position if position > 0.0 else 0.0
            self.position = position if position < _POSITION_MAX else _POSITION_MAX
            self.velocity = move / dt
        else:
            self.velocity = 0.0
        load = self._load(drives)
        self._heat(dt, load)
        if self._shut_down_if_alarmed() & d[_ALARM_SHUTDOWN]:
            drives = self.drives()
            load = self._load(drives)
        self._write_present(drives, load)

    def _heat(self, dt: float, load: float) -> None:
        if self.forced_temperature is not None:
            self.temperature = self.forced_temperature
            return
        env = self.env
        target = env.ambient_c + env.heat_gain_c * load**2
        self.temperature += (target - self.temperature) * (1 - math.exp(-dt / env.thermal_tau_s))

    def plant_update(
        self, raw: float, velocity: float, torque: float, saturated: bool, dt: float
    ) -> None:
        """A physics plant's joint state: position (raw units), velocity (raw units/s), the
        motor's torque (N·m) and whether it was held at its torque limit over ``dt`` s."""
        self._place(raw)
        self.velocity = float(velocity) if self.powered else 0.0
        self.plant_torque = float(torque)
        self.saturated_s = self.saturated_s + dt if saturated else 0.0
        self._sync_registers()

    def set_position(self, raw: float) -> None:
        """The world moves the horn (a limp joint pushed, a robot placed)."""
        self._place(raw)
        self._sync_registers()

    def _place(self, raw: float) -> None:
        # Each servo at each physics round: min(POSITION_MAX, max(0.0, ·)) as comparisons.
        position = float(raw)
        position = position if position > 0.0 else 0.0
        self.position = position if position < _POSITION_MAX else _POSITION_MAX

    def _sync_registers(self) -> None:
        drives = self.drives()
        self._write_present(drives, self._load(drives))

    def _write_present(self, drives: bool, load: float) -> None:
        # Every step of every servo, twice a physics round under a physics plant (its step,
        # then its new state): the bytes written in place at the registers' addresses, the same
        # values the table's item access and units' encoders would write, each computed in the
        # same order of operations.
        d = self.table.data
        position = round(self.position)
        d[_PRESENT_POSITION] = position & 0xFF
        d[_PRESENT_POSITION + 1] = (position >> 8) & 0xFF
        speed_units = self.velocity * 60.0 / _UNITS_PER_REV / _RPM_PER_SPEED_UNIT
        speed = _encode_signed_11bit(round(speed_units))
        d[_PRESENT_SPEED] = speed & 0xFF
        d[_PRESENT_SPEED + 1] = speed >> 8
        load_units = _encode_signed_11bit(round(load * 100.0 / _LOAD_PERCENT_PER_UNIT))
        d[_PRESENT_LOAD] = load_units & 0xFF
        d[_PRESENT_LOAD + 1] = load_units >> 8
        volts = round(self.env.voltage * 10)  # max(0, min(255, ·)) as comparisons
        volts = volts if volts < 255 else 255
        d[_PRESENT_VOLTAGE] = volts if volts > 0 else 0
        celsius = round(self.temperature)
        celsius = celsius if celsius < 255 else 255
        d[_PRESENT_TEMPERATURE] = celsius if celsius > 0 else 0
        moving = (
            drives
            and abs((d[_GOAL_POSITION] | (d[_GOAL_POSITION + 1] << 8)) - self.position) >= 1.0
        )
        d[_MOVING] = 1 if moving else 0


def _imu_layout(
    gyro_axes: tuple[tuple[CM730, int], ...], accel_axes: tuple[tuple[CM730, int], ...]
) -> tuple[object, object, tuple[int, ...], tuple[int, ...], tuple[int, ...]]:
    """An axis map as the CM-730's refresh uses it: the two maps (to see it is the same), the
    signs of each, and the six registers' addresses in the map's order."""
    return (
        gyro_axes,
        accel_axes,
        tuple(s for _, s in gyro_axes),
        tuple(s for _, s in accel_axes),
        tuple(m.value.address for m, _ in (*gyro_axes, *accel_axes)),
    )


class CM730Device(Device):
    """The sub-controller: power switch for the servo bus, LEDs, buttons, IMU and voltage."""

    def __init__(
        self,
        env: Environment,
        rng: np.random.Generator,
        imu_noise: float = 1.0,
        gyro_full_scale_dps: float = units.GYRO_DPS_FULL_SCALE,
    ) -> None:
        super().__init__(ControlTable(CM730, CM730_TABLE_SIZE), env)
        self.rng = rng
        self.imu_noise = imu_noise
        self.gyro_full_scale_dps = gyro_full_scale_dps
        self.gyro = (0.0, 0.0, 0.0)  # rad/s, robot axes
        self.accel = (0.0, 0.0, units.GRAVITY)  # specific force, m/s², robot axes: upright
        self.on_power = lambda on: None  # set by the bus: DXL_POWER writes switch the servos
        self._imu_layout: tuple[object, object, tuple[int, ...], tuple[int, ...], tuple[int, ...]]
        self._imu_layout = ((), (), (), (), ())  # made at the first read (refresh)
        # The six raw readings before noise, and what they were converted from: a body at
        # rest feels the same between reads, and a world step sets each vector at most once.
        self._imu_raws: tuple[tuple[object, ...], tuple[int, ...]] = ((), ())

    def after_write(self, changed: list) -> int:
        if CM730.DXL_POWER.reg in changed:
            self.on_power(bool(self.table[CM730.DXL_POWER]))
        return self.alarm_bits()

    def refresh(self) -> None:
        # Before every read of the CM-730 (each bulk read, 125 a second): the bytes in place.
        # The conversions are units' own, called once an axis (two zips and an enum lookup
        # per axis were most of the CM-730's read; tests/unit/test_sim_imu_registers.py).
        d = self.table.data
        volts = round(self.env.voltage * 10)  # max(0, min(255, ·)) as comparisons
        volts = volts if volts < 255 else 255
        d[_CM730_VOLTAGE] = volts if volts > 0 else 0
        # The axis map is read here, each time (a test flips its signs to see the balance
        # feedback throw the robot over); its signs and addresses are kept while it is the same.
        layout = self._imu_layout
        if layout[0] is not IMU_GYRO_AXES or layout[1] is not IMU_ACCEL_AXES:
            layout = self._imu_layout = _imu_layout(IMU_GYRO_AXES, IMU_ACCEL_AXES)
        addresses = layout[4]
        inputs = (layout, self.gyro, self.accel, self.gyro_full_scale_dps)
        converted = self._imu_raws
        if converted[0] != inputs:
            converted = self._imu_raws = (inputs, self._imu_convert(layout))
        raws: Sequence[float] = converted[1]
        if self.imu_noise > 0:
            # One draw of six: the generator gives the same numbers as six draws of one.
            noise = self.rng.normal(0.0, self.imu_noise, 6).tolist()
            raws = [r + n for r, n in zip(raws, noise, strict=True)]
        for address, raw in zip(addresses, raws, strict=True):
            value = round(raw)
            if value < 0:
                value = 0
            elif value > _IMU_MAX:
                value = _IMU_MAX
            d[address] = value & 0xFF
            d[address + 1] = value >> 8

    def _imu_convert(
        self,
        layout: tuple[object, object, tuple[int, ...], tuple[int, ...], tuple[int, ...]],
    ) -> tuple[int, ...]:
        _, _, (s0, s1, s2), (s3, s4, s5), _ = layout
        gx, gy, gz = self.gyro
        ax, ay, az = self.accel
        fs = self.gyro_full_scale_dps
        gyro_raw, accel_raw = units.rad_s_to_gyro_raw, units.ms2_to_accel_raw
        return (
            gyro_raw(s0 * gx, fs),
            gyro_raw(s1 * gy, fs),
            gyro_raw(s2 * gz, fs),
            accel_raw(s3 * ax),
            accel_raw(s4 * ay),
            accel_raw(s5 * az),
        )

    def set_buttons(self, mask: int) -> None:
        self.table[CM730.BUTTON] = mask & 0x03
