"""docs/learning.md: every shell command it shows runs and says what the page says."""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from tests.fixtures.system import RunningSystem

PAGE = Path(__file__).resolve().parents[2] / "docs" / "learning.md"


def _commands() -> list[str]:
    blocks = re.findall(r"```sh\n(.*?)```", PAGE.read_text(), re.S)
    return [line for b in blocks for line in b.splitlines() if line.startswith("darwin ")]


def test_the_page_commands_run_and_the_example_outlasts_the_hold() -> None:
    commands = [c for c in _commands() if c.startswith("darwin policy ")]
    assert len(commands) == 2
    stood = []
    for cmd in commands:
        argv = shlex.split(cmd)[1:]
        res = subprocess.run(
            [sys.executable, "-m", "robot_daemon.launch.cli", *argv],
            capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL,
        )  # fmt: skip
        assert res.returncode == 0, res.stderr
        stood.append(res.stdout.splitlines()[-1])
    assert stood[0] == "stood: 10.00 s of 10 s (standing)"
    assert stood[1].endswith("(fell)")


def test_the_page_record_command_writes_a_dataset(
    robot_system: RunningSystem, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (command,) = [c for c in _commands() if c.startswith("darwin record ")]
    monkeypatch.setenv("DARWIN_ENDPOINT", robot_system.endpoint)
    monkeypatch.setenv("DARWIN_ROBOT", robot_system.robot)
    res = subprocess.run(
        [sys.executable, "-m", "robot_daemon.launch.cli", *shlex.split(command)[1:]],
        capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL, cwd=tmp_path,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    # The shared system runs without a camera: the page says the recorder says so in one line.
    assert "no camera image" in res.stderr
    info = json.loads((tmp_path / "stand-data" / "meta" / "info.json").read_text())
    assert info["total_episodes"] == 1 and info["total_frames"] > 0
    assert info["video_path"] is None


def test_the_page_python_examples_run(
    robot_system: RunningSystem, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    stream_example, env_example = re.findall(r"```python\n(.*?)```", PAGE.read_text(), re.S)
    exec(compile(env_example, str(PAGE), "exec"), {})
    monkeypatch.setenv("DARWIN_ENDPOINT", robot_system.endpoint)
    monkeypatch.setenv("DARWIN_ROBOT", robot_system.robot)
    exec(compile(stream_example, str(PAGE), "exec"), {})
    # target (20 rad), clipped (capped by max_delta unless the robot already stood there), latency
    out = capsys.readouterr().out.strip()
    target = re.match(r"\[([^\]]*)\]", out)
    assert target is not None and len(target.group(1).split(",")) == 20
    assert float(out.rsplit(" ", 1)[1]) > 0
