"""What the daemon does when the battery and heat policy changes level (robot_daemon/
power_policy.py), on the motion thread at the status rate: warn → one event; sit → stop every
motion, play the sit-down page, limit the torque; off → torque off (every servo for the battery,
the hot servo for heat: it cools down limp). Recovery only says so: torque and motion come back
when someone commands them."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

from robot_daemon.bus.tables import MX28
from robot_daemon.motion.action.player import ActionModule
from robot_daemon.power_policy import LEVELS, PowerPolicy, load_settings

log = logging.getLogger(__name__)

SIT_PAGE = "sit down"
# Commands that make the robot work: refused from the sit level on (``refusal``).
MOVES = frozenset({"walk", "playball", "choreography"})


class PowerGuard:
    def __init__(
        self,
        robot: Any,
        settings: dict[str, Any],
        manager: Any,
        bus: Any,
        emit: Callable[..., None],
    ) -> None:
        power, heat = load_settings(settings)
        self.policy = PowerPolicy(power, heat, {j: robot.by_id[j].name for j in robot.ids})
        self.robot = robot
        self.manager = manager
        self.bus = bus
        self.emit = emit
        self.cost_s = 0.0  # process CPU time spent in the policy (benchmark, status)
        self.runs = 0

    def check(self, voltage: float, temperature: Any, online: Any, now: float) -> None:
        t0 = time.process_time()
        temps = {j: float(temperature[j]) for j in self.robot.ids if online[j]}
        for kind, level, message, data in self.policy.update(voltage, temps, now):
            self.emit(kind, message, level=level, **data)
            if level != "ok" and self.policy.power_settings.beep:
                self._say(message)
            try:
                self._act(kind, level, data)
            except Exception as exc:  # a bus error must not end the loop: said, retried never
                log.warning("%s %s: acting failed: %s", kind, level, exc)
        self.cost_s += time.process_time() - t0
        self.runs += 1

    def _say(self, message: str) -> None:
        # The CM-730 has no buzzer register (ROBOTIS Framework CM730.h: nothing between BUTTON
        # 30 and GYRO_Z 38; its firmware beeps by itself near 10 V): the robot says it through
        # the [sound] player instead, an event in the simulator.
        choreography = self.manager.get("choreography")
        player = getattr(choreography, "sound", None)
        if player is not None:
            try:
                player.play(self.emit, say=message)
            except ValueError as exc:  # no player installed: the event above says it anyway
                log.info("cannot say %r: %s", message, exc)

    def _act(self, kind: str, level: str, data: dict[str, Any]) -> None:
        # The protective actions MOVE_POWER_SIT and MOVE_POWER_OFF (robot_daemon/
        # motion_authority.py).
        if level == "sit":
            self.manager.stop_all()
            player = self.manager.get("action")
            if isinstance(player, ActionModule):
                try:
                    player.play(SIT_PAGE)
                except (KeyError, ValueError) as exc:
                    log.warning("cannot sit down: %s", exc)
            limit = int(self.policy.power_settings.torque_limit * 1023)
            address = MX28.TORQUE_LIMIT.reg.address
            for j in self.robot.ids:
                self.bus.write_registers(j, address, limit.to_bytes(2, "little"))
        elif level == "off":
            ids = list(self.robot.ids) if kind == "power" else [int(data["id"])]
            for module in self.manager.modules:
                owned = module.owned() & set(ids)
                if owned:
                    module.release(owned)
            self.bus.set_torque(ids, False)
        elif level == "ok" and self.policy.battery.level == 0 and self.policy.heat_level < 2:
            address = MX28.TORQUE_LIMIT.reg.address
            for j in self.robot.ids:
                self.bus.write_registers(j, address, (1023).to_bytes(2, "little"))

    def refusal(self, verb: str, fields: dict[str, Any]) -> str | None:
        """Why a command that would make the robot work is refused now (None: it is not):
        from sit on (battery or a servo's heat), walking, ball play and choreographies wait
        until the level is back below sit; stops, pages (standing up), halt always pass."""
        if verb not in MOVES or fields.get("op") == "stop":
            return None
        if self.policy.battery.level >= 2:
            return (
                f"battery at {self.policy.voltage:.1f} V ({LEVELS[self.policy.battery.level]} "
                f"level of the [power] policy): {verb} refused; charge or swap the battery"
            )
        if self.policy.heat_level >= 2:
            # The servo whose level it is (it may have cooled below the others since and still
            # be within its hysteresis and hold time), not whichever is hottest now.
            j = max(
                self.policy.servos,
                key=lambda k: (self.policy.servos[k].level, self.policy.temps.get(k, 0.0)),
            )
            celsius = self.policy.temps.get(j, 0.0)
            return (
                f"servo {j} ({self.policy.names[j]}) at {celsius:.0f} °C "
                f"({LEVELS[self.policy.heat_level]} level of the [heat] policy): {verb} refused; "
                "let it cool down"
            )
        return None

    def status(self) -> tuple[dict[str, Any], dict[str, Any]]:
        return self.policy.power_info(), self.policy.heat_info()
