"""Emulator settings: shipped defaults, a user file on top, command-line overrides on top."""

from __future__ import annotations

from pathlib import Path

import pytest

from robot_daemon.emulator import EmulatorSettings
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
    from robot_daemon.emulator.settings import EmulatorSettings
    from schemas.errors import ConfigError

    assert EmulatorSettings.from_dict({}).physics == "kinematic"
    assert EmulatorSettings.from_dict({"physics": "mujoco"}).physics == "mujoco"
    with pytest.raises(ConfigError, match="physics='bullet' is not a plant"):
        EmulatorSettings.from_dict({"physics": "bullet"})


def test_a_wrongly_typed_emulator_value_is_named() -> None:
    with pytest.raises(ConfigError, match=r"\[emulator\] voltage = 'high' should be a number"):
        EmulatorSettings.from_dict({"voltage": "high"})


def test_shipped_world_config_reads_in_radians_and_splits_the_camera_table() -> None:
    import math

    from config.loader import load_all
    from robot_daemon.plant.world_settings import WorldSettings

    s = WorldSettings.from_config(load_all()["world"])
    assert s.robot_start == (-1.0, 0.0, 0.0) and s.ball_start == (-0.4, 0.0)
    assert s.falls.tilt_limit == pytest.approx(math.radians(40.0))
    assert s.falls.stand_tilt == pytest.approx(math.radians(20.0))
    assert (s.render.camera.width, s.render.camera.fov_h_deg, s.render.blur) == (320, 58.0, True)
    assert s.ball.color == (210, 28, 28) and s.field.length == 9.0
    turned = WorldSettings.from_config({"robot_start": [0, 1, 90], "ball_start": []})
    assert turned.robot_start == (0.0, 1.0, pytest.approx(math.pi / 2))
    assert turned.ball_start is None


@pytest.mark.parametrize(
    ("world", "named"),
    [
        ({"camera": {"widht": 320}}, r"\[world.camera\] has an unknown setting 'widht'.*'width'"),
        ({"falls": {"tilt_limt_deg": 30}}, r"\[world.falls\].*'tilt_limt_deg'"),
        ({"field": {"lenght": 9}}, r"\[world.field\].*'lenght'.*'length'"),
        ({"publish_hz": "fast"}, r"\[world\] publish_hz = 'fast' should be a number"),
        ({"ball_start": [1.0]}, r"ball_start = \[1.0\] should be \[x, y\]"),
    ],
)
def test_world_config_mistakes_are_named(world: dict, named: str) -> None:
    from robot_daemon.plant.world_settings import WorldSettings

    with pytest.raises(ConfigError, match=named):
        WorldSettings.from_config(world)


def test_physics_sub_tables_fill_the_flat_settings_and_refuse_strangers() -> None:
    from config.loader import load_all
    from robot_daemon.plant.physics.mjcf_model import PhysicsSettings

    s = PhysicsSettings.from_config(load_all())
    assert (s.timestep, s.stall_torque, s.foot_condim, s.fall_tilt_deg) == (0.001, 2.5, 3, 60.0)
    assert s.solref == (0.02, 1.0)
    with pytest.raises(ConfigError, match=r"\[physics.servo\].*'stall_torqe'.*'stall_torque'"):
        PhysicsSettings.from_config({"physics": {"servo": {"stall_torqe": 2.0}}})
    with pytest.raises(ConfigError, match=r"\[physics\] has an unknown setting 'timestpe'"):
        PhysicsSettings.from_config({"physics": {"timestpe": 0.001}})


@pytest.mark.parametrize("command", ["robot_daemon.plant.sim_cli", "robot_daemon.launch.up"])
def test_darwin_sim_and_up_take_the_same_physics_option(command: str) -> None:
    import argparse
    import importlib

    parser = argparse.ArgumentParser()
    importlib.import_module(command).add_arguments(parser)
    assert parser.parse_args(["--physics", "mujoco"]).physics == "mujoco"
    assert parser.parse_args([]).physics is None  # the config's [emulator] physics decides
    with pytest.raises(SystemExit):
        parser.parse_args(["--physics", "bullet"])


@pytest.mark.parametrize("command", ["robot_daemon.launch.daemon_cli", "robot_daemon.launch.up"])
def test_programs_starting_the_emulator_forward_the_same_options(command: str) -> None:
    import argparse
    import importlib

    parser = argparse.ArgumentParser()
    importlib.import_module(command).add_arguments(parser)
    args = parser.parse_args(["--sim-arg=--drop=0.1", "--sim-arg=--seed=3", "--no-wire-timing"])
    assert (args.sim_arg, args.wire_timing) == (["--drop=0.1", "--seed=3"], False)
    args = parser.parse_args([])
    assert (args.sim_arg, args.wire_timing) == ([], None)  # None: the emulator's own default
