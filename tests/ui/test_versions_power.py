"""The TUI (and so the web UI, the same app) against a daemon of another protocol major: the
header says which versions and what to upgrade; against a sagging battery and a hot servo: the
header shows the policy's level and the hottest servo."""

from __future__ import annotations

from pathlib import Path

import pytest

from clients.tui.messages import LinkState
from schemas.sim_control import SimControl
from schemas.versions import ENV_ANNOUNCE, PROTOCOL_VERSION
from tests.fixtures.system import start_system
from tests.ui.live import connected, live_app, until


def _header(app) -> str:
    return str(app.screen.query_one("RobotHeader").render())


async def test_an_incompatible_daemon_is_named_in_the_header(
    settings_file: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(ENV_ANNOUNCE, f"{PROTOCOL_VERSION[0] + 1}.0")
    with start_system(gateway=False) as system:
        app = live_app(system, settings_file, "tui-old")
        async with app.run_test(size=(160, 40)) as pilot:
            await until(pilot, lambda: "incompatible" in _header(app), "the refusal in the header")
            assert app.link_info.state is LinkState.UNREACHABLE
            assert f"speaks {PROTOCOL_VERSION[0] + 1}.0" in app.link_info.detail


async def test_battery_level_and_hottest_servo_in_the_header(
    settings_file: Path, tmp_path: Path
) -> None:
    config = tmp_path / "power.toml"
    config.write_text("[power]\nhold_s = 0.5\n[heat]\nhold_s = 0.5\n")
    with start_system(gateway=False, extra_args=["--config", str(config)]) as system:
        app = live_app(system, settings_file, "tui-power")
        async with app.run_test(size=(160, 40)) as pilot:
            await connected(pilot)
            assert "warn" not in _header(app)  # nothing past ok: the header as before
            robot = app.link.robot
            sim = SimControl(robot.session, system.robot)
            sim.call("voltage", volts=10.9)
            sim.call("overheat", id=5, on=True, celsius=66.0)
            await until(pilot, lambda: "warn" in _header(app), "the battery level")
            await until(pilot, lambda: "66 °C warn" in _header(app), "the hottest servo")


async def test_a_minor_skew_is_a_notification(
    settings_file: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(ENV_ANNOUNCE, f"{PROTOCOL_VERSION[0]}.{PROTOCOL_VERSION[1] + 1}")
    with start_system(gateway=False) as system:
        app = live_app(system, settings_file, "tui-older")
        async with app.run_test(size=(160, 40)) as pilot:
            await connected(pilot)
            await until(
                pilot,
                lambda: any("upgrade this client" in str(n.message) for n in app._notifications),
                "the skew's notification",
            )
