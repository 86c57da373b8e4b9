"""The battery and heat policy: graded levels ok → warn → sit → off, for the supply voltage and
for each servo's temperature (docs/power.md).

A level is entered when its threshold has been crossed for ``hold_s`` without a break (a walk's
current spikes pull the voltage down for tens of milliseconds: they never trip it), and left only
when the value is back past the threshold by ``hysteresis`` for ``hold_s`` (no flapping). Each
change of level is one event. The daemon evaluates it at the status rate (10 Hz), not per tick.

What the daemon does on entering a level (``robot_daemon/engine/power_actions.py``): warn → an event
(every UI shows ``status.power``/``status.heat``) and the robot says it (``beep``); sit → stop
the motion, play the sit-down page and limit the torque; off → torque off. The MX-28's own
overheat shutdown (its Limit Temperature, 80 °C by default, ROBOTIS e-manual MX-28 address 11)
stays the last resort: the policy's thresholds sit below it.
"""

from __future__ import annotations

from dataclasses import dataclass
from operator import itemgetter
from typing import Any

from config.loader import ranged, section_to

LEVELS = ("ok", "warn", "sit", "off")


@dataclass(frozen=True)
class PowerSettings:
    """``[power]``: supply voltage thresholds (V); a 3-cell LiPo is 12.6 V full, ~11.1 V
    nominal; the DARwIn-OP's CM-730 itself beeps near 10.5 V."""

    enabled: bool = True
    warn_v: float = ranged(11.0, 0.0)
    sit_v: float = ranged(10.5, 0.0)
    off_v: float = ranged(10.0, 0.0)
    hysteresis_v: float = ranged(0.3, 0.0)
    hold_s: float = ranged(2.0, 0.0)
    beep: bool = True  # say each level past ok through the [sound] player (power_actions.py)
    torque_limit: float = ranged(0.5, 0.0, 1.0)  # fraction of max torque once sitting


@dataclass(frozen=True)
class HeatSettings:
    """``[heat]``: per-servo temperature thresholds (°C), below the MX-28's own limit."""

    enabled: bool = True
    warn_c: float = ranged(65.0, 0.0)
    sit_c: float = ranged(70.0, 0.0)
    off_c: float = ranged(75.0, 0.0)
    hysteresis_c: float = ranged(5.0, 0.0)
    hold_s: float = ranged(2.0, 0.0)
    hottest: int = ranged(3, 1)  # how many of the hottest servos status.heat lists


def load_settings(settings: dict[str, Any]) -> tuple[PowerSettings, HeatSettings]:
    power = section_to(PowerSettings, settings.get("power", {}), "power")
    heat = section_to(HeatSettings, settings.get("heat", {}), "heat")
    if not power.warn_v > power.sit_v > power.off_v:
        raise ValueError("[power] needs warn_v > sit_v > off_v")
    if not heat.warn_c < heat.sit_c < heat.off_c:
        raise ValueError("[heat] needs warn_c < sit_c < off_c")
    return power, heat


class Graded:
    """One graded quantity: thresholds in order warn, sit, off; ``rising`` when a higher value
    is worse (temperature), else a lower one is (voltage)."""

    def __init__(
        self, thresholds: tuple[float, float, float], hysteresis: float, hold_s: float, rising: bool
    ) -> None:
        self.thresholds = thresholds
        self.hysteresis = hysteresis
        self.hold_s = hold_s
        self.rising = rising
        self.level = 0
        self._want = 0  # the level the value asks for, and since when
        self._since = 0.0

    def _worse(self, value: float, threshold: float) -> bool:
        return value >= threshold if self.rising else value <= threshold

    def _target(self, value: float) -> int:
        level = 0
        for i, threshold in enumerate(self.thresholds, start=1):
            if self._worse(value, threshold):
                level = i
        if level < self.level:
            # Leaving a level needs the value back past its threshold by the hysteresis.
            back = self.hysteresis if self.rising else -self.hysteresis
            while level < self.level and self._worse(value + back, self.thresholds[level]):
                level += 1
        return level

    @property
    def pending(self) -> int:
        """The level the value last asked for (the level itself unless one is being held)."""
        return self._want

    def update(self, value: float, now: float) -> int | None:
        """The new level when it changes now, else None."""
        want = self._target(value)
        if want == self.level:
            self._want, self._since = want, now
            return None
        if want != self._want:
            self._want, self._since = want, now
        if now - self._since < self.hold_s:
            return None
        self.level = want
        return want


class PowerPolicy:
    """Battery and per-servo heat: ``update`` at ~10 Hz returns the transitions as
    (kind, level name, message, data)."""

    def __init__(self, power: PowerSettings, heat: HeatSettings, names: dict[int, str]) -> None:
        self.power_settings = power
        self.heat_settings = heat
        self.names = names
        self.battery = Graded(
            (power.warn_v, power.sit_v, power.off_v), power.hysteresis_v, power.hold_s, False
        )
        self.servos = {
            j: Graded((heat.warn_c, heat.sit_c, heat.off_c), heat.hysteresis_c, heat.hold_s, True)
            for j in names
        }
        self.voltage = 0.0
        self.temps: dict[int, float] = {}
        self._heat_quiet = True  # every servo at level 0 with no other level pending

    def update(
        self, voltage: float, temps: dict[int, float], now: float
    ) -> list[tuple[str, str, str, dict[str, Any]]]:
        out: list[tuple[str, str, str, dict[str, Any]]] = []
        self.voltage, self.temps = voltage, temps
        if self.power_settings.enabled and voltage > 0.0:  # 0: the CM-730 not read yet
            new = self.battery.update(voltage, now)
            if new is not None:
                name = LEVELS[new]
                out.append(("power", name, f"battery {voltage:.1f} V: {name}", {"volts": voltage}))
        if self.heat_settings.enabled:
            # A quiet robot below warn everywhere: nothing can change (each servo's update
            # would find level 0 asked for at level 0), so one max() instead of twenty
            # updates, ~0.1 M instructions a status message on the robot's Python.
            if self._heat_quiet and (not temps or max(temps.values()) < self.heat_settings.warn_c):
                return out
            for j, celsius in temps.items():
                graded = self.servos.get(j)
                new = graded.update(celsius, now) if graded is not None else None
                if new is not None:
                    name = LEVELS[new]
                    joint = self.names[j]
                    out.append(
                        (
                            "heat",
                            name,
                            f"servo {j} ({joint}) {celsius:.0f} °C: {name}",
                            {"id": j, "name": joint, "celsius": celsius},
                        )
                    )
            self._heat_quiet = all(g.level == 0 and g.pending == 0 for g in self.servos.values())
        return out

    @property
    def heat_level(self) -> int:
        if self._heat_quiet:  # every servo at level 0
            return 0
        return max((g.level for g in self.servos.values()), default=0)

    def power_info(self) -> dict[str, Any]:
        return {"level": LEVELS[self.battery.level], "volts": round(self.voltage, 2)}

    def heat_info(self) -> dict[str, Any]:
        # Hottest first, equals in id order: a stable sort, descending (``reverse`` keeps the
        # order of equals), by a C key rather than a Python one per servo.
        hot = sorted(self.temps.items(), key=itemgetter(1), reverse=True)
        hot = hot[: self.heat_settings.hottest]
        quiet = self._heat_quiet
        return {
            "level": LEVELS[0 if quiet else self.heat_level],
            "hottest": [{"id": j, "name": self.names[j], "celsius": c} for j, c in hot],
            "alarms": [] if quiet else [j for j, g in self.servos.items() if g.level > 0],
        }
