"""The emulator's run-time API: the world's seam, faults on demand, and a snapshot of its state.

A part the :class:`~robot_daemon.emulator.emulator.Emulator` has (``emu.api``), made over what
it reads and changes: the emulator's lock, its servo chain, the environment (supply, ambient),
the fault settings, the seed and the serving statistics. Angles are servo angles in rad (raw
2048 = 0), as :mod:`schemas.units` converts them.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from robot_daemon.bus.tables import CM730, MX28
from schemas import units

if TYPE_CHECKING:
    from robot_daemon.emulator.devices import Environment
    from robot_daemon.emulator.faults import Faults
    from robot_daemon.emulator.servo_chain import Bus

BUTTONS = {"mode": 0x01, "start": 0x02}


def _vector(name: str, value: Sequence[float]) -> tuple[float, float, float]:
    values = [float(v) for v in value]
    if len(values) != 3:
        raise ValueError(f"{name} needs 3 values (x, y, z in robot axes), got {len(values)}")
    return values[0], values[1], values[2]


class EmulatorApi:
    """Every method takes the emulator's lock, so each is thread-safe."""

    def __init__(
        self,
        lock: threading.RLock,
        bus: Bus,
        env: Environment,
        faults: Faults,
        seed: int,
        stats: dict[str, int],
    ) -> None:
        self.lock = lock
        self.bus = bus
        self.env = env
        self.faults = faults
        self.seed = seed
        self.stats = stats  # the serving thread's counters, read here

    # ---- the world's seam ---------------------------------------------------------------------

    def present_positions(self) -> dict[int, float]:
        """Servo angle (rad) of every servo by ID, powered or not."""
        with self.lock:
            return {i: float(units.raw_to_rad(s.position)) for i, s in self.bus.servos.items()}

    def goal_positions(self) -> dict[int, float]:
        with self.lock:
            return {
                i: float(units.raw_to_rad(s.table[MX28.GOAL_POSITION]))
                for i, s in self.bus.servos.items()
            }

    def torque_enabled(self) -> dict[int, bool]:
        with self.lock:
            return {
                i: bool(s.powered and s.table[MX28.TORQUE_ENABLE])
                for i, s in self.bus.servos.items()
            }

    def set_present_position(self, dxl_id: int, rad: float) -> None:
        """Move a servo's horn from outside (a limp joint pushed, the robot placed)."""
        raw = units.rad_to_raw(rad)
        if not 0 <= raw <= units.POSITION_MAX:
            raise ValueError(
                f"{rad} rad is outside the servo's range (raw {raw}, 0..{units.POSITION_MAX})"
            )
        with self.lock:
            self.bus.servo(dxl_id).set_position(raw)

    def set_external_load(self, dxl_id: int, fraction: float) -> None:
        """Torque the world applies on a servo, as a signed fraction of its maximum."""
        with self.lock:
            self.bus.servo(dxl_id).external_load = max(-1.0, min(1.0, float(fraction)))

    def set_body_motion(
        self,
        gyro_rad_s: Sequence[float] = (0.0, 0.0, 0.0),
        accel_ms2: Sequence[float] = (0.0, 0.0, units.GRAVITY),
    ) -> None:
        """What the CM-730's IMU feels, in robot axes (x forward, y left, z up).

        ``accel_ms2`` is the specific force, gravity included: upright and still is (0, 0, +g).
        """
        gyro, accel = _vector("gyro_rad_s", gyro_rad_s), _vector("accel_ms2", accel_ms2)
        with self.lock:
            self.bus.cm730.gyro, self.bus.cm730.accel = gyro, accel

    # ---- faults and inputs --------------------------------------------------------------------

    def set_faults(
        self,
        drop: float | None = None,
        corrupt: float | None = None,
        delay: float | None = None,
        delay_ms: float | None = None,
    ) -> dict[str, float]:
        with self.lock:
            old = (self.faults.drop, self.faults.corrupt, self.faults.delay, self.faults.delay_ms)
            for name, value in (
                ("drop", drop),
                ("corrupt", corrupt),
                ("delay", delay),
                ("delay_ms", delay_ms),
            ):
                if value is not None:
                    setattr(self.faults, name, float(value))
            try:
                self.faults.check()
            except ValueError:
                self.faults.drop, self.faults.corrupt, self.faults.delay, self.faults.delay_ms = old
                raise
            return self.fault_state()

    def fault_state(self) -> dict[str, Any]:
        with self.lock:
            return {
                "drop": self.faults.drop,
                "corrupt": self.faults.corrupt,
                "delay": self.faults.delay,
                "delay_ms": self.faults.delay_ms,
                "silent_ids": sorted(self.bus.silent),
                "overheat_ids": sorted(
                    i for i, s in self.bus.servos.items() if s.forced_temperature is not None
                ),
                "voltage": self.env.voltage,
                "broken_after": list(self.bus.broken_after),
                "fresh_servos": sorted(self.bus.fresh),
            }

    def silence(self, dxl_id: int, silent: bool = True) -> None:
        """A device that stops answering (it still obeys writes)."""
        with self.lock:
            if dxl_id != self.bus.cm730.id:
                self.bus.servo(dxl_id)  # a clear error for an unknown ID
            if silent:
                self.bus.silent.add(dxl_id)
            else:
                self.bus.silent.discard(dxl_id)

    def overheat(self, dxl_id: int, on: bool = True, celsius: float | None = None) -> None:
        """Pin a servo 5 °C above its limit (or at ``celsius``); off brings it back to the
        ambient temperature."""
        with self.lock:
            servo = self.bus.servo(dxl_id)
            if on:
                above = servo.table[MX28.TEMPERATURE_LIMIT] + 5.0
                servo.forced_temperature = above if celsius is None else float(celsius)
                servo.temperature = servo.forced_temperature
            else:
                servo.forced_temperature = None
                servo.temperature = self.env.ambient_c
            servo.step(1e-6)  # alarm and shutdown take effect at once

    def set_voltage(self, volts: float) -> None:
        if not 0.0 <= volts <= 25.5:
            raise ValueError(f"voltage {volts} V is outside 0..25.5 V")
        with self.lock:
            self.env.voltage = float(volts)

    def press_button(self, name: str, pressed: bool = True) -> None:
        if name not in BUTTONS:
            raise ValueError(f"unknown button {name!r}; buttons: {', '.join(BUTTONS)}")
        with self.lock:
            mask = self.bus.cm730.table[CM730.BUTTON]
            mask = mask | BUTTONS[name] if pressed else mask & ~BUTTONS[name]
            self.bus.cm730.set_buttons(mask)

    # ---- inspection -----------------------------------------------------------------------------

    def register(self, dxl_id: int, name: str) -> int:
        """A register's value by name, straight from the table (tests and debugging)."""
        with self.lock:
            dev = self.bus.cm730 if dxl_id == self.bus.cm730.id else self.bus.servo(dxl_id)
            kind = dev.table.kind
            if name not in kind.__members__:
                raise KeyError(
                    f"no register {name!r} on device {dxl_id} ({kind.__name__}); "
                    f"registers: {', '.join(kind.__members__)}"
                )
            dev.refresh()
            return dev.table[kind[name]]

    def state(self) -> dict[str, Any]:
        """A plain snapshot (msgpack-able) for the control API and debugging."""
        with self.lock:
            cm = self.bus.cm730
            servos = {}
            for i, s in self.bus.servos.items():
                t = s.table
                servos[str(i)] = {
                    "position": float(units.raw_to_rad(s.position)),
                    "goal": float(units.raw_to_rad(t[MX28.GOAL_POSITION])),
                    "torque": bool(t[MX28.TORQUE_ENABLE]),
                    # 0 after an alarm shutdown: limp whatever TORQUE_ENABLE says
                    "torque_limit": int(t[MX28.TORQUE_LIMIT]),
                    "temperature": round(s.temperature, 2),
                    "alarm": s.alarm_bits() if s.powered else 0,
                    "powered": s.powered,
                }
            return {
                "seed": self.seed,
                "sim_time": self.bus.time,
                "dxl_power": bool(cm.table[CM730.DXL_POWER]),
                "servo_power": self.bus.servo_power,
                "leds": {
                    "panel": cm.table[CM730.LED_PANEL],
                    "head": cm.table[CM730.LED_HEAD],
                    "eye": cm.table[CM730.LED_EYE],
                },
                "buttons": cm.table[CM730.BUTTON],
                "imu": {"gyro": list(cm.gyro), "accel": list(cm.accel)},
                "faults": self.fault_state(),
                "stats": dict(self.stats),
                "servos": servos,
            }
