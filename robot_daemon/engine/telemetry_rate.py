"""How often the tick's telemetry (joints, IMU) goes out: every tick, or at most
``[daemon] telemetry_hz`` on a computer that cannot afford a message per tick.

ros2_control lets a broadcaster run slower than the control loop for the same reason. The
loop itself (bulk read, balance, fall monitor, goals) is unaffected: only what is published.
"""

from __future__ import annotations

from schemas.errors import ConfigError


def check_rate(value: object, setting: str) -> float:
    """``value`` as a rate in Hz (0 = every tick), or ``ConfigError`` naming ``setting``."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0 <= value < 1e6:
        raise ConfigError(f"{setting} must be 0 (every tick) or a rate in Hz, not {value!r}")
    return float(value)


class RateGate:
    """Opens on the tick nearest each multiple of ``1 / hz`` (0: on every tick).

    The average rate is exact and each interval is within a tick of ``1 / hz`` (at 50 Hz on
    8 ms ticks: 16, 24, 16, 24 ms), so a recorder's timeline is not drifting. After a stall
    the gate opens once and starts again from there: no burst to catch up.
    """

    def __init__(self, hz: float, tick_s: float) -> None:
        self.hz = hz
        self.period = 1.0 / hz if hz > 0 else 0.0
        self.half_tick = tick_s / 2
        self._due: float | None = None

    def open(self, now: float) -> bool:
        if not self.period:
            return True
        due = self._due
        if due is not None and now < due - self.half_tick:
            return False
        due = now if due is None else due
        due += self.period
        self._due = due if due > now else now + self.period
        return True
