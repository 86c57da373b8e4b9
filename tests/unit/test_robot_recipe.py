"""docs/robot.md's recipe as scripts/i386-check reads it (the check itself needs root and the
network and runs from scripts/test): one install block, one daemon command, and the apt packages
the robot's Python takes instead of wheels PyPI does not have for 32-bit Linux."""

from __future__ import annotations

import importlib.util
import shlex
import sys
import tomllib
from pathlib import Path
from types import ModuleType

from robot_daemon.engine.telemetry_rate import check_rate

REPO = Path(__file__).resolve().parents[2]


def load_check() -> ModuleType:
    spec = importlib.util.spec_from_file_location("i386_check", REPO / "scripts" / "i386_check.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["i386_check"] = module
    spec.loader.exec_module(module)
    return module


def test_the_recipe_installs_the_daemon_first_and_has_one_daemon_command() -> None:
    check = load_check()
    blocks, command = check.recipe()
    packages = check.apt_packages(blocks)
    install = blocks[0]
    for needed in ("python3-venv", "python3-numpy", "python3-opencv", "python3-serial",
                   "python3-msgpack"):
        assert needed in packages
    assert "python3 -m venv --system-site-packages /opt/darwin" in install
    assert "/opt/darwin/bin/pip install ~/darwin-zenoh" in install
    words = shlex.split(command)
    assert words[:2] == ["/opt/darwin/bin/darwin", "daemon"]
    assert check.ROBOT_PORT in words and check.ROBOT_LISTEN in words


def test_fenced_blocks_are_found_by_their_info_string_only() -> None:
    check = load_check()
    text = ("```sh\nnot me\n```\n```{.sh .recipe}\necho a\necho b\n```\n"
            "```{.sh .recipe-x}\nno\n```\n")
    assert check.fenced_blocks(text, check.RECIPE) == ["echo a\necho b\n"]


def test_the_core_requirements_are_the_ones_the_check_dry_runs() -> None:
    check = load_check()
    reqs = check.core_requirements()
    assert any(r.startswith("eclipse-zenoh") for r in reqs)
    assert any(r.startswith("numpy>=1.24") for r in reqs)


def test_opencv_comes_after_the_daemon_and_blocks_are_named_by_their_comment() -> None:
    check = load_check()
    blocks, _ = check.recipe()
    assert "python3-opencv" not in blocks[0]
    names = [check.label(b) for b in blocks]
    assert names == [
        "the daemon",
        "the compiled hot path, optional",
        "OpenCV, for the camera and ball play",
        "the loop's settings for the Atom",
    ]


def test_the_atom_settings_are_settings_the_daemon_knows() -> None:
    """The config the recipe writes (and the robot-run command reads) names only settings of
    the shipped [daemon] table, with values the daemon takes."""
    check = load_check()
    blocks, command = check.recipe()
    block = blocks[-1]
    body = block.split("<<'EOF'\n", 1)[1].split("\nEOF", 1)[0]
    path = shlex.split(block.split("cat > ", 1)[1])[0]
    assert f"--config {path}" in command
    written = tomllib.loads(body)["daemon"]
    shipped = tomllib.loads((REPO / "config" / "daemon.toml").read_text())["daemon"]
    assert set(written) <= set(shipped)
    assert check_rate(written["telemetry_hz"], "daemon.telemetry_hz") > 0
    assert 0 < written["servo_reads_per_tick"] < 20
