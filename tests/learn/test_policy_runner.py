"""`darwin policy run`: policies load (Python callable, ONNX), the shipped example outlasts
holding the stand under pushes, and the runner drives a real stack (and only publishes in a
dry run)."""

from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from clients.learn.examples import stand_balance
from clients.learn.runner import PolicyLoadError, load_policy, run_sim
from schemas.messages import decode
from schemas.policy import N_JOINTS, OBSERVATION_SIZE, PolicyAction
from tests.fixtures.system import RunningSystem
from tests.integration.test_motion_system import WAIT

EXAMPLE = "clients.learn.examples.stand_balance"


def test_the_example_policy_stands_longer_under_pushes_than_holding_the_pose() -> None:
    policy, rate = load_policy(f"{EXAMPLE}:policy")
    hold, _ = load_policy(f"{EXAMPLE}:hold")
    assert rate == 50.0
    seeds, push, seconds = range(3), 12.0, 8.0
    with_policy, holding = [], []
    for seed in seeds:
        stand_balance.policy.reset()
        with_policy.append(run_sim(policy, 50.0, seconds, push, seed))
        holding.append(run_sim(hold, 50.0, seconds, push, seed))
    print(f"steps standing under {push} N pushes: policy {with_policy}, hold {holding}")
    assert sum(with_policy) > sum(holding)
    assert all(p >= h for p, h in zip(with_policy, holding, strict=True))


def test_an_onnx_policy_loads_and_runs(tmp_path: Path) -> None:
    onnx = pytest.importorskip("onnx", reason="building a test model needs the onnx package")
    pytest.importorskip("onnxruntime", reason="ONNX policies need the learn extra")
    from onnx import TensorProto, helper

    w = helper.make_tensor(
        "w", TensorProto.FLOAT, [OBSERVATION_SIZE, N_JOINTS], [0.0] * OBSERVATION_SIZE * N_JOINTS
    )
    graph = helper.make_graph(
        [helper.make_node("MatMul", ["obs", "w"], ["action"])],
        "zero",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, [1, OBSERVATION_SIZE])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, [1, N_JOINTS])],
        [w],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    from clients.learn.onnx_policy import deploy_metadata

    helper.set_model_props(model, deploy_metadata(25.0, 0.3, [32] * N_JOINTS))
    path = tmp_path / "zero.onnx"
    onnx.save(model, str(path))
    policy, rate = load_policy(str(path))
    assert rate == 25.0
    assert policy(np.ones(OBSERVATION_SIZE, np.float32)).tolist() == [0.0] * N_JOINTS
    assert run_sim(policy, 25.0, 1.0, 0.0, 0) == 25  # stood the whole second
    # --sim steps at the model's action scale, as the stream on a robot is started at it.
    from clients.learn.fast import FastBackend

    scales: list[float] = []
    real_reset = FastBackend.reset

    def reset(self: FastBackend, *args: object, **kwargs: object) -> object:
        scales.append(self.scale)
        return real_reset(self, *args, **kwargs)  # type: ignore[arg-type]

    helper.set_model_props(model, deploy_metadata(25.0, 0.9, [32] * N_JOINTS))
    onnx.save(model, str(path))
    wide, _ = load_policy(str(path))
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(FastBackend, "reset", reset)
        assert run_sim(wide, 25.0, 0.2, 0.0, 0) == 5
    assert scales == [0.9]
    (tmp_path / "bad.onnx").write_bytes(b"not a model")
    with pytest.raises(PolicyLoadError, match="not a loadable ONNX model"):
        load_policy(str(tmp_path / "bad.onnx"))


def _darwin(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "robot_daemon.launch.cli", *args],
        capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL,
    )  # fmt: skip


def test_bad_policy_files_get_one_line() -> None:
    res = _darwin("policy", "run", "no_such_module:fn", "--sim")
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert res.stderr.strip().startswith("darwin policy: cannot import no_such_module")
    res = _darwin("policy", "run", f"{EXAMPLE}:nothing", "--sim")
    assert "has no callable 'nothing'" in res.stderr


def test_the_runner_drives_the_stack_and_a_dry_run_only_publishes(
    robot_system: RunningSystem,
) -> None:
    where = ["--connect", robot_system.endpoint, "--robot", robot_system.robot]
    res = _darwin("policy", "run", f"{EXAMPLE}:policy", "--seconds", "1.5", *where)
    assert res.returncode == 0, res.stdout + res.stderr
    lines = res.stdout.splitlines()
    assert lines[0] == f"policy: {EXAMPLE}:policy at 50 Hz"
    summary = lines[-1]
    assert summary.startswith("actions: ") and "applied" in summary
    sent = int(summary.split()[1])
    assert sent > 0
    with robot_system.robot_client(name="dry-run watcher") as watcher:
        seen: list[PolicyAction] = []
        got = threading.Event()

        def on(sample: object) -> None:
            seen.append(decode(sample.payload.to_bytes(), PolicyAction))  # type: ignore[attr-defined]
            got.set()

        sub = watcher.session.declare_subscriber(watcher.keys.policy("dry_run"), on)
        res = _darwin("policy", "run", f"{EXAMPLE}:hold", "--seconds", "1", "--dry-run", *where)
        assert res.returncode == 0, res.stdout + res.stderr
        assert got.wait(WAIT) and seen[0].action == [0.0] * N_JOINTS
        assert "published (dry run)" in res.stdout
        status = watcher.wait_for("status", timeout=WAIT)
        assert status.lease is None  # the dry run never took the lease
        sub.undeclare()
