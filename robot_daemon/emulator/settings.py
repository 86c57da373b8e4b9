"""Emulator settings: the ``[emulator]`` config section, overridable field by field."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from config.loader import load_all, ranged, section_to
from robot_daemon.emulator.options import PLANTS
from schemas.errors import ConfigError


@dataclass
class EmulatorSettings:
    """The ``[emulator]`` section, with how the emulator is reached and clocked."""

    seed: int = 0  # 0: a fresh seed, logged so the run can be replayed
    wire_timing: bool = True
    baud: int = 1_000_000
    power_on_delay_s: float = 0.3
    voltage: float = 12.0
    imu_noise: float = 1.0
    gyro_full_scale_dps: float = 500.0
    max_step_s: float = 0.01
    idle_step_s: float = 0.02
    packet_timeout_s: float = 0.01
    # > 0: deliver replies as an FTDI USB chip does (62-byte USB packets, the rest when this
    # latency timer fires; robot_daemon/emulator/ftdi.py); 0: each reply when its last byte is in.
    # 1 ms, as the robot's adapter is set (the daemon refuses a slower one): the host sees the
    # robot's handful of deliveries a tick, not 21.
    ftdi_latency_ms: float = ranged(1.0, 0.0, 255.0)
    drop: float = 0.0
    corrupt: float = 0.0
    delay: float = 0.0
    delay_ms: float = 50.0
    silent_ids: list[int] = field(default_factory=list)
    # The CM-730 ignores this many READ/BULK_READ instructions first (a late CM-730).
    cm730_late_reads: int = 0
    # First-session behaviours of real servos (robot_daemon/emulator/bringup.py).
    old_firmware_ids: list[int] = field(default_factory=list)
    leftover_ram_ids: list[int] = field(default_factory=list)
    sag_units: float = 0.0
    overheat_ids: list[int] = field(default_factory=list)
    # A cable break right after each of these servos hides the ones behind it on its branch.
    broken_after: list[int] = field(default_factory=list)
    # This servo is swapped for a factory-fresh MX-28 (ID 1, 57,600 bps); 0: none.
    fresh_servo: int = 0
    ambient_c: float = 35.0
    heat_gain_c: float = 70.0
    thermal_tau_s: float = 60.0
    # SCHED_FIFO priority of the serving thread, so replies leave when the wire model says
    # however busy the computer (servos answer on time; a starved emulator made the daemon see
    # them go offline); below the daemon's loop (40). 0 = normal scheduling.
    realtime_priority: int = 30
    # SCHED_FIFO priority of the physics thread, below the serving thread (config/emulator.toml
    # says why). 0 = normal scheduling.
    physics_priority: int = 20
    # The plant behind the servos: "kinematic" (no extra dependency) or "mujoco" (physics,
    # `pip install -e '.[physics]'`; its numbers in config/physics.toml).
    physics: str = "kinematic"
    # Not in the config file: how the emulator is reached and clocked.
    link: str | None = None
    realtime: bool = True  # False: time moves only through Emulator.advance(dt)
    initial_positions: dict[int, int] = field(default_factory=dict)

    @classmethod
    def load(cls, path: str | None = None, **overrides: Any) -> EmulatorSettings:
        """Shipped ``[emulator]`` values, the user file on top, then ``overrides`` (not None)."""
        return cls.from_settings(load_all(path), **overrides)

    @classmethod
    def from_settings(cls, data: dict[str, Any], **overrides: Any) -> EmulatorSettings:
        """From merged config ``data`` (its ``[emulator]``, and ``[imu]``'s gyro scale, which
        the daemon reads the emulated IMU with), then ``overrides`` (not None)."""
        section = dict(data.get("emulator", {}))
        gyro = data.get("imu", {}).get("gyro_full_scale_dps")
        if gyro is not None:
            section.setdefault("gyro_full_scale_dps", gyro)
        section.update({k: v for k, v in overrides.items() if v is not None})
        return cls.from_dict(section)

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> EmulatorSettings:
        settings = section_to(cls, values, "emulator")
        if settings.physics not in PLANTS:
            raise ConfigError(
                f"[emulator] physics={settings.physics!r} is not a plant; use {' or '.join(PLANTS)}"
            )
        return settings
