"""The battery and heat policy on the emulator: the supply voltage ramped down walks warn → sit
→ torque off, one event each in order; recovery; a heating servo raises its alarm and the
policy acts; status carries both (what every UI shows)."""

from __future__ import annotations

from pathlib import Path

import pytest

from schemas.errors import UnavailableError
from schemas.sim_control import SimControl
from tests.fixtures.system import EventLog, run_darwin, start_system


def test_voltage_ramp_and_heating_servo(tmp_path: Path) -> None:
    config = tmp_path / "power.toml"
    config.write_text("[power]\nhold_s = 0.5\n[heat]\nhold_s = 0.5\n")
    with (
        start_system(gateway=False, extra_args=["--config", str(config)]) as system,
        system.robot_client(name="battery") as robot,
    ):
        sim = SimControl(robot.session, system.robot)
        events = EventLog()
        robot.subscribe("events", events)
        robot.wait_for("status", lambda s: s.power.get("level") == "ok", timeout=30)
        for volts, level in ((10.9, "warn"), (10.4, "sit"), (9.8, "off")):
            sim.call("voltage", volts=volts)
            robot.wait_for("status", lambda s, lv=level: s.power["level"] == lv, timeout=15)
        sat = events.wait(lambda e: e.kind == "action" and e.data["state"] == "started")
        assert sat.data["name"] == "sit down"
        with robot.control(), pytest.raises(UnavailableError, match="charge or swap"):
            robot.walk(x=0.02)  # a flat battery does not walk again
        status = robot.wait_for("status", lambda s: len(s.bus["torque_off"]) == 20, timeout=15)
        assert status.power["volts"] < 10.0
        sim.call("voltage", volts=12.0)
        robot.wait_for("status", lambda s: s.power["level"] == "ok", timeout=15)
        events.wait(lambda e: e.kind == "power" and e.data["level"] == "ok")
        power = [e.data["level"] for e in events.items if e.kind == "power"]
        assert power == ["warn", "sit", "off", "ok"]
        said = [e.data["say"] for e in events.items if e.kind == "sound"]
        assert said[:3] == [
            f"battery {v} V: {lv}" for v, lv in (("10.9", "warn"), ("10.4", "sit"), ("9.8", "off"))
        ]

        sim.call("overheat", id=5, on=True, celsius=71.0)
        status = robot.wait_for("status", lambda s: 5 in s.heat.get("alarms", []), timeout=15)
        assert status.heat["hottest"][0]["id"] == 5 and status.heat["level"] == "sit"
        heat = events.wait(lambda e: e.kind == "heat" and e.data["id"] == 5)
        assert heat.data["level"] == "sit" and "servo 5" in heat.message
        hot = status.heat["hottest"][0]["name"]
        listed = run_darwin("list", "--connect", system.endpoint, "--robot", system.robot)
        assert f"hottest {hot} 71 °C" in listed.stdout, listed.stdout + listed.stderr
        sim.call("overheat", id=5, on=False)
        robot.wait_for("status", lambda s: s.heat["level"] == "ok", timeout=15)
