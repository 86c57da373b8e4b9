"""Emulator settings: shipped defaults, a user file on top, command-line overrides on top."""

from __future__ import annotations

from pathlib import Path

import pytest

from robot_daemon.sim import EmulatorSettings
from schemas.errors import ConfigError


def test_shipped_defaults_match_the_real_bus() -> None:
    s = EmulatorSettings.load()
    assert (s.wire_timing, s.baud, s.power_on_delay_s, s.voltage) == (True, 1_000_000, 0.3, 12.0)
    assert (s.drop, s.corrupt, s.delay, s.silent_ids) == (0.0, 0.0, 0.0, [])


def test_user_file_then_overrides(tmp_path: Path) -> None:
    user = tmp_path / "user.toml"
    user.write_text("[emulator]\nvoltage = 11.1\nsilent_ids = [7]\nseed = 5\n")
    s = EmulatorSettings.load(str(user), seed=9, drop=None)
    assert (s.voltage, s.silent_ids, s.seed, s.drop) == (11.1, [7], 9, 0.0)


def test_unknown_settings_are_named(tmp_path: Path) -> None:
    user = tmp_path / "user.toml"
    user.write_text("[emulator]\nwire_timming = false\n")
    with pytest.raises(ConfigError, match="wire_timming"):
        EmulatorSettings.load(str(user))


def test_physics_plant_is_checked() -> None:
    from robot_daemon.sim.settings import EmulatorSettings
    from schemas.errors import ConfigError

    assert EmulatorSettings.from_dict({}).physics == "kinematic"
    assert EmulatorSettings.from_dict({"physics": "mujoco"}).physics == "mujoco"
    with pytest.raises(ConfigError, match="physics='bullet' is not a plant"):
        EmulatorSettings.from_dict({"physics": "bullet"})
