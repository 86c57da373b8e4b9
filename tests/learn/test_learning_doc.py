"""docs/learning.md: every shell command it shows runs and says what the page says."""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from tests.fixtures.system import RunningSystem

PAGE = Path(__file__).resolve().parents[2] / "docs" / "learning.md"


def _commands(prefix: str = "darwin ") -> list[str]:
    blocks = re.findall(r"```sh\n(.*?)```", PAGE.read_text(), re.S)
    return [line for b in blocks for line in b.splitlines() if line.startswith(prefix)]


def _cli(argv: list[str], **kw: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "robot_daemon.launch.cli", *argv],
        capture_output=True, text=True, stdin=subprocess.DEVNULL, **kw,  # type: ignore[call-overload]
    )  # fmt: skip


def test_the_page_commands_run_and_the_example_outlasts_the_hold() -> None:
    commands = [c for c in _commands("darwin policy ") if "examples.stand_balance" in c]
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


def test_the_page_training_command_improves_the_return_and_writes_a_policy(
    tmp_path: Path,
) -> None:
    (command,) = _commands("python -m clients.learn.train ")
    res = subprocess.run(
        [sys.executable, *shlex.split(command)[1:]],
        capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL, cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(PAGE.parents[1])},
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert lines[-1] == "policy: stand_push.onnx"
    before, after = map(float, re.findall(r"untrained ([-\d.]+), trained ([-\d.]+)", lines[-2])[0])
    print(lines[-2])
    assert after > before  # the deterministic policy's return on the same seeded shoves
    from clients.learn.runner import load_policy

    _, rate = load_policy(str(tmp_path / "stand_push.onnx"), "numpy")  # the contract's
    assert rate == 50.0


def test_the_shipped_policy_evaluates_in_simulation() -> None:
    (command,) = [c for c in _commands("darwin policy ") if "--sim" in c and ".onnx" in c]
    res = _cli(shlex.split(command)[1:], timeout=300, cwd=PAGE.parents[1])
    assert res.returncode == 0, res.stderr
    assert res.stdout.splitlines()[0].endswith("at 50 Hz (onnxruntime)")
    assert res.stdout.splitlines()[-1].startswith("stood: ")


def test_the_shipped_policy_runs_on_the_simulated_stack_and_as_on_the_robot(
    tmp_path: Path,
) -> None:
    from tests.fixtures.system import start_system
    from tests.learn.test_env_backends import PATIENT

    # The run is of the policy, not of this machine's scheduling: a starved test process must
    # not find the joints damped (missed deadlines) and the robot sagging into a fall.
    patient = tmp_path / "patient.toml"
    patient.write_text(PATIENT)

    commands = [c for c in _commands("darwin policy ") if ".onnx" in c and "--sim" not in c]
    assert len(commands) == 2 and "--engine numpy" in commands[1]
    for command, engine in zip(commands, ("onnxruntime", "numpy"), strict=True):
        # A fresh `darwin up` each: the page's two are different places (the simulator, the
        # robot), and a run's end leaves the joints soft before its safe stop.
        args = ["--physics", "mujoco", "--config", str(patient)]
        with start_system(gateway=False, extra_args=args) as system:
            env = {**os.environ, "DARWIN_ENDPOINT": system.endpoint, "DARWIN_ROBOT": system.robot}
            argv = shlex.split(command)[1:]
            argv[argv.index("--seconds") + 1] = "2"  # the page's 10 s, shorter
            res = _cli(argv, timeout=120, cwd=PAGE.parents[1], env=env)
            assert res.returncode == 0, res.stdout + res.stderr
            lines = res.stdout.splitlines()
            assert lines[0].endswith(f"at 50 Hz ({engine})")
            # `darwin up` leaves the servos centred (legs straight): the run stood the robot in
            # the default pose first, or its first actions would have jumped the joints there.
            assert lines[2].startswith("pose: played the stand page (r_knee was 0.93 rad"), lines
            # It streamed until --seconds and the daemon applied what came. How many: a starved
            # test process sends fewer (the daemon holds the targets meanwhile); the rate is
            # benchmarks/learn_benchmark.py's, whether a policy stands a shove push_table.py's.
            # Lost: actions the daemon never received (seqs skipped on the way in).
            summary = r"actions: (\d+) sent, applied (\d+), missed deadlines \d+, lost (\d+)"
            done = re.fullmatch(summary, lines[-1])
            assert done is not None and 0 < int(done[2]) <= int(done[1]), lines[-1]
            assert int(done[2]) + int(done[3]) <= int(done[1]), lines[-1]


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
    # target (20 rad), clipped, latency
    out = capsys.readouterr().out.strip()
    target = re.match(r"\[([^\]]*)\]", out)
    assert target is not None and len(target.group(1).split(",")) == 20
    assert float(out.rsplit(" ", 1)[1]) > 0
