"""The LeRobot plugin package (plugins/lerobot_robot_darwin): nothing else depends on LeRobot,
and with LeRobot installed it drives the simulated robot through the policy stream."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

from tests.fixtures.system import RunningSystem

ROOT = Path(__file__).resolve().parents[2]
PLUGIN = ROOT / "plugins" / "lerobot_robot_darwin"


def test_only_the_plugin_imports_lerobot() -> None:
    files = subprocess.run(
        ["git", "grep", "-l", "-E", r"^\s*(from|import) lerobot", "--", "*.py"],
        cwd=ROOT, capture_output=True, text=True, check=False,
    ).stdout.split()  # fmt: skip
    # The plugin, and tests that are skipped without LeRobot.
    allowed = ("plugins/lerobot_robot_darwin/", "tests/learn/")
    assert files and all(f.startswith(allowed) for f in files), files
    # LeRobot discovers installed packages by this name prefix.
    assert (PLUGIN / "lerobot_robot_darwin" / "__init__.py").is_file()
    assert 'name = "lerobot_robot_darwin"' in (PLUGIN / "pyproject.toml").read_text()


@pytest.mark.skipif(
    importlib.util.find_spec("lerobot") is None,
    reason="lerobot is not installed (it pulls torch; not a dependency of this project)",
)
def test_the_plugin_sends_actions_and_returns_what_was_applied(
    robot_system: RunningSystem,
) -> None:
    sys.path.insert(0, str(PLUGIN))
    from lerobot_robot_darwin import Darwin, DarwinConfig

    robot = Darwin(DarwinConfig(endpoint=robot_system.endpoint, robot=robot_system.robot))
    robot.connect()
    try:
        obs = robot.get_observation()
        assert set(obs) == set(robot.observation_features)
        sent = robot.send_action(dict.fromkeys(robot.action_features, 5.0))
        assert max(sent.values()) <= 1.0  # clipped, and said so
    finally:
        robot.disconnect()
