"""The core install (`pip install darwin-zenoh`, no extras) holds what the robot's daemon needs:
every daemon module imports and `darwin daemon --help` runs with the extras' packages refusing
to import (tests/no_extras.py), a laptop command without its extra says so in one line, and the
extras in pyproject.toml are the ones schemas/extras.py names."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from schemas.extras import EXTRA_OF

REPO = Path(__file__).resolve().parents[2]
NO_EXTRAS = REPO / "tests" / "no_extras.py"

# Modules that need an extra by design: certificate creation (`darwin certs`, `--mtls`).
NEED_AN_EXTRA = {"robot_daemon.security.certs", "robot_daemon.security.certs_cli"}


def no_extras(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(NO_EXTRAS), *args], capture_output=True, text=True, timeout=120
    )


def robot_side_modules() -> list[str]:
    """Every module of the packages the robot runs (the daemon, the gateway, the schemas, the
    config), plus the Robot client a script on the robot may use."""
    out = ["clients", "clients.robot", "clients.dataframes"]
    for package in ("robot_daemon", "schemas", "config", "gateway"):
        for path in sorted((REPO / package).rglob("*.py")):
            parts = path.relative_to(REPO).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            if name not in NEED_AN_EXTRA:
                out.append(name)
    return out


def test_the_robots_modules_import_without_any_extra() -> None:
    proc = no_extras("import", *robot_side_modules())
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_the_blocker_really_blocks() -> None:
    proc = no_extras("import", "robot_daemon.security.certs", "clients.tui.app")
    assert proc.returncode == 1
    assert "No module named 'cryptography'" in proc.stdout
    assert "No module named 'textual'" in proc.stdout


def test_darwin_daemon_help_runs_without_any_extra() -> None:
    proc = no_extras("darwin", "daemon", "--help")
    assert proc.returncode == 0, proc.stderr
    assert "usage: darwin daemon" in proc.stdout
    assert "--port" in proc.stdout


@pytest.mark.parametrize(
    ("command", "extra"),
    [
        (["tui"], "tui"),
        (["web"], "web"),
        (["foxglove"], "foxglove"),
        (["record", "-o", "x.mcap"], "record"),
        (["ros2"], "ros2"),
        (["certs", "--help"], "security"),
    ],
)
def test_a_laptop_command_without_its_extra_is_one_line(command: list[str], extra: str) -> None:
    proc = no_extras("darwin", *command)
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert proc.stderr == (
        f"darwin {command[0]}: needs the {extra!r} extra: pip install -e '.[{extra}]' in the "
        "project's clone\n"
    )


@pytest.mark.parametrize(
    ("call", "expected"),
    [
        (
            "from robot_daemon.vision.ball_finder import BallFinder, FinderSettings\n"
            "from config.loader import load_all\n"
            "BallFinder(FinderSettings.from_config(load_all(None)['ballplay']))\n",
            "ball finding: needs the 'vision' extra: pip install -e '.[vision]' in the project's "
            "clone "
            "(on the robot: apt-get install python3-opencv)",
        ),
        (
            "from clients.dataframes import to_frame\nto_frame('joints', [])\n",
            "DataFrames: needs the 'notebook' extra: pip install -e '.[notebook]' in the "
            "project's clone",
        ),
    ],
)
def test_a_feature_without_its_package_names_the_extra(call: str, expected: str) -> None:
    body = "try:\n" + "".join(f"    {line}\n" for line in call.splitlines())
    body += "except ModuleNotFoundError as exc:\n    print(exc)\n"
    proc = subprocess.run(
        [sys.executable, "-c", _with_blocker(body)],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=REPO,
    )
    assert proc.stdout == expected + "\n", proc.stderr


def _with_blocker(body: str) -> str:
    return (
        "import sys\n"
        f"sys.path.insert(0, {str(REPO / 'tests')!r})\n"
        "import no_extras\n"
        "sys.meta_path.insert(0, no_extras._Absent())\n" + body
    )


def test_pyproject_extras_match_the_modules_they_provide() -> None:
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]
    assert set(EXTRA_OF.values()) <= set(extras)
    everything = extras["all"][0]
    for extra in extras:
        if extra not in {"all", "test"}:
            assert extra in everything, f"[all] leaves out [{extra}]"
    assert "darwin-zenoh[all]" in extras["test"]
    core = {dep.split(">")[0].split("=")[0].split("<")[0] for dep in project["dependencies"]}
    assert core == {"eclipse-zenoh", "dynamixel-sdk", "pyserial", "msgpack", "numpy"}
