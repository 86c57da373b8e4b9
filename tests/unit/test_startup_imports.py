"""What each program of ``darwin up`` loads before it can start (``benchmarks/startup_benchmark.py``
measures the time; this holds the causes): the launcher does not load the daemon's engine or the
emulator, the daemon loads its engine only once it has started the emulator, no child reads every
installed package's metadata to find its own command, the gateway starts without numpy (as
every client of :class:`clients.robot.Robot` does), and a simulated world nobody watches loads
no camera.

Each case runs in a fresh interpreter: ``darwin NAME``'s module imported and its parser built,
as ``darwin NAME`` does before running."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

ENGINE = "robot_daemon.engine.daemon"
EMULATOR = "robot_daemon.emulator.emulator"
METADATA = "importlib.metadata"  # what finding a command among every installed package costs
MESSAGES = "schemas.messages"  # the wire's classes: `darwin up` serves nothing
INTERNAL = "robot_daemon.security.internal"  # identities of --auth/--secure only
OFFSETS = "clients.calibration"  # a client's offset editor, with the user file's writer
V4L2 = "robot_daemon.vision.v4l2"  # a device camera's
FINDER = "robot_daemon.vision.ball_finder"  # ball play's
RENDER = "robot_daemon.plant.render"  # the simulated camera's
FLEET_JOIN = "robot_daemon.engine.fleet_join"  # a daemon's check session to its router
EMULATOR_SETTINGS = "robot_daemon.emulator.settings"  # `darwin sim`'s: the others forward options
ROBOTIS_OFFSETS = "config.robotis_offsets"  # ROBOTIS's file, read by a daemon on a real robot
FLEET = "clients.fleet"  # a client's discovery of every robot (`darwin list`)
TOML = "tomllib"  # the parser: the shipped files are read from their parsed copies

# command → modules it must not have loaded once its parser is built
NOT_BEFORE_START = {
    "up": {ENGINE, EMULATOR, "numpy", MESSAGES, INTERNAL, FLEET_JOIN, EMULATOR_SETTINGS, TOML},
    "daemon": {ENGINE, EMULATOR, "numpy", METADATA, EMULATOR_SETTINGS, ROBOTIS_OFFSETS, TOML},
    "sim": {METADATA, TOML, "subprocess"},  # it starts no child (robot_daemon.launch.child_side)
    "gateway": {"numpy", METADATA, OFFSETS, "uuid", FLEET, TOML, "ctypes"},  # nor the gateway
}


def _loaded_by(code: str, watched: set[str]) -> set[str]:
    """The modules of ``watched`` a fresh interpreter has loaded once it ran ``code``."""
    shown = f"print(' '.join(m for m in {sorted(watched)!r} if m in sys.modules))"
    code = f"{code}\nimport sys\n{shown}\n"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    return set(out.stdout.split())


def _loaded(command: str, watched: set[str]) -> set[str]:
    return _loaded_by(
        f"from robot_daemon.launch.cli import command_parser\ncommand_parser({command!r})",
        watched,
    )


@pytest.mark.parametrize("command", sorted(NOT_BEFORE_START))
def test_a_program_of_darwin_up_starts_without_what_it_does_not_need(command: str) -> None:
    assert _loaded(command, NOT_BEFORE_START[command]) == set()


def test_the_watched_modules_are_real_names() -> None:
    """The test above would pass on a misspelt name: each is what a heavier program loads."""
    watched = set().union(*NOT_BEFORE_START.values(), {V4L2, FINDER, RENDER})
    code = (
        "import sys, importlib.metadata, numpy, uuid, tomllib, subprocess, ctypes\n"
        f"import {ENGINE}, {EMULATOR}, {MESSAGES}, {INTERNAL}, {OFFSETS}, {V4L2}, {FINDER}\n"
        f"import {RENDER}, {FLEET_JOIN}, {EMULATOR_SETTINGS}, {ROBOTIS_OFFSETS}, {FLEET}\n"
        f"print(' '.join(m for m in {sorted(watched)!r} if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert set(out.stdout.split()) == watched


def test_the_daemon_loads_a_device_camera_and_ball_play_only_when_used() -> None:
    """Its engine, its verbs and its camera check with no camera (as every test's daemon)."""
    code = (
        f"import {ENGINE}, robot_daemon.arbiter.verbs.ballplay\n"
        "from robot_daemon.vision.sources import check_spec\n"
        "check_spec('none')"
    )
    assert _loaded_by(code, {V4L2, FINDER}) == set()


def test_a_simulated_world_nobody_watches_loads_no_camera() -> None:
    """``darwin sim``'s world as ``darwin up --camera none`` starts it: its settings name the
    camera's lens and field, but neither the renderer nor the ball finder is loaded until a
    frame is drawn."""
    code = (
        "import argparse\n"
        "from robot_daemon.plant.world_link import world_from_args\n"
        "world_from_args(argparse.Namespace()).snapshot()"
    )
    assert _loaded_by(code, {RENDER, FINDER}) == set()


def test_shipped_files_parsed_before_are_read_without_the_toml_parser() -> None:
    """Every program reads the shipped config at start, and the daemon its motion library:
    once parsed (:func:`config.loader.toml_file` keeps them as bytecode is kept), a start loads
    neither the files' text nor the parser. The first run parses and keeps them (also where
    PYTHONDONTWRITEBYTECODE is set for the tests' shell: scripts/test unsets it)."""
    code = (
        "from config.loader import load_all, robot_from_dict\n"
        "from robot_daemon.motion.action.store import PageStore\n"
        "robot = robot_from_dict(load_all()['robot'])\n"
        "PageStore({j.id: j.name for j in robot.joints}, None, '/nonexistent')\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    for _ in range(2):  # the first may parse them (and keep them), the second must not
        shown = f"import sys\nprint({TOML!r} in sys.modules)\n"
        out = subprocess.run(
            [sys.executable, "-c", code + shown],
            capture_output=True, text=True, check=True, timeout=120, env=env,
        )  # fmt: skip
    assert out.stdout.split() == ["False"]


def test_a_client_of_a_daemon_of_its_own_protocol_reads_no_package_metadata() -> None:
    """The version check names both packages' versions only when the protocols differ."""
    code = (
        "import sys\n"
        "from schemas.versions import PROTOCOL_VERSION, check_daemon\n"
        "status = {'protocol': list(PROTOCOL_VERSION), 'version': '0.1.0', 'robot': 'op1'}\n"
        "assert check_daemon(status, 'darwin test') is None\n"
        f"print({METADATA!r} in sys.modules)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout.split() == ["False"]


def test_the_version_is_defined_once_and_announced_without_package_metadata() -> None:
    """``schemas.versions`` defines it and the installed metadata reads it from there
    (pyproject.toml), so the daemon's engine announces it without importlib.metadata (60 ms of
    CPU at each start)."""
    from importlib.metadata import version

    code = (
        "import sys\n"
        f"import {ENGINE}\n"
        "from schemas.versions import PACKAGE_VERSION\n"
        f"print({METADATA!r} in sys.modules, PACKAGE_VERSION)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    loaded, announced = out.stdout.split()
    assert loaded == "False"
    assert announced == version("darwin-zenoh")


def test_units_make_their_tables_on_first_use() -> None:
    """The loop's tables, made lazily, are the conversions they stand for and stay module
    attributes (a plain lookup in the loop)."""
    import numpy as np

    from schemas import units

    raw = np.arange(0x800)
    assert np.array_equal(units.SPEED_RAD_S_TABLE, units.speed_raw_to_rad_s(raw))
    assert "SPEED_RAD_S_TABLE" in vars(units)
    assert units.signed_11bit(0x400 | 7) == -7
    assert list(units.signed_11bit(np.array([0x400 | 7, 7]))) == [-7, 7]
    with pytest.raises(AttributeError):
        units.NO_SUCH_TABLE  # noqa: B018


def test_a_held_child_runs_only_when_let_go() -> None:
    """``darwin up`` starts its adapters held (their imports overlap the daemon's start): one
    let go runs, one stopped while held ends without having run (no output at all)."""
    from robot_daemon.launch.children import Child

    let_go = Child("urdf", ["urdf"], held=True)
    never = Child("urdf", ["urdf"], held=True)
    try:
        let_go.go()
        assert let_go.wait_line("<robot", timeout=60).startswith('name="darwin_op"')
        never.stop(timeout=60)
    finally:
        for child in (let_go, never):
            child.stop()
            child._reader.join(timeout=10)  # its pipes read to the end, then closed
            child._err_reader.join(timeout=10)
            for stream in (child.proc.stdout, child.proc.stderr):
                if stream is not None:
                    stream.close()
    assert never.output == [] and never.errors == []


def test_the_classes_darwin_up_makes_at_start_carry_their_own_docstrings() -> None:
    """Python 3.11 writes a dataclass without a docstring one from its signature, formatting
    every field's annotation at each class creation: about 0.3 ms a class, 90 of them at each
    robot start. What the four programs load before they serve (their engines included) brings
    its own."""
    packages = ("robot_daemon", "schemas", "config", "clients", "gateway")
    code = (
        "import argparse, dataclasses, inspect, sys\n"
        "from robot_daemon.launch.cli import command_parser\n"
        "for name in ('up', 'daemon', 'sim', 'gateway'):\n"
        "    command_parser(name)\n"
        f"import {ENGINE}, {EMULATOR}, gateway.server, robot_daemon.launch.adapter_logins\n"
        "from robot_daemon.plant.world_link import world_from_args\n"
        "world_from_args(argparse.Namespace())\n"
        "for mod in list(sys.modules.values()):\n"
        f"    if not mod.__name__.startswith({packages!r}):\n"
        "        continue\n"
        "    for cls in vars(mod).values():\n"
        "        if not (dataclasses.is_dataclass(cls) and isinstance(cls, type)\n"
        "                and cls.__module__ == mod.__name__):\n"
        "            continue\n"
        "        made = cls.__name__ + str(inspect.signature(cls)).replace(' -> None', '')\n"
        "        if cls.__doc__ == made:\n"
        "            print(f'{mod.__name__}.{cls.__qualname__}')\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout.split() == []
