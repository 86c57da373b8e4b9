"""ONNX policies without onnxruntime: the numpy evaluator agrees with onnxruntime, refuses a
graph it cannot evaluate naming the operator, and a model made for another contract is refused
naming the mismatch (clients/learn/onnx_policy.py)."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from clients.learn.onnx_policy import (
    META_JOINTS,
    META_SCHEMA,
    SUPPORTED_OPS,
    NumpyGraph,
    PolicyLoadError,
    contract_mismatch,
    deploy_metadata,
    load_onnx,
    mlp_model,
)
from clients.learn.runner import load_policy, run_sim
from clients.learn.train import ARS_SCALES
from schemas.joints import JOINT_NAMES
from schemas.policy import N_JOINTS, OBSERVATION_SIZE

onnx = pytest.importorskip("onnx", reason="building test models needs the onnx package")
from onnx import TensorProto, helper, numpy_helper  # noqa: E402

P_GAINS = [32] * N_JOINTS


def _random_mlp(rng: np.random.Generator, hidden: tuple[int, ...]) -> list:
    sizes = (OBSERVATION_SIZE, *hidden, N_JOINTS)
    return [
        (rng.normal(0, 1 / np.sqrt(a), (a, b)), rng.normal(0, 0.1, b))
        for a, b in itertools.pairwise(sizes)
    ]


def _save(model, path: Path) -> str:  # type: ignore[no-untyped-def]
    onnx.save(model, str(path))
    return str(path)


@pytest.mark.parametrize("activation", ["Tanh", "Relu", "Elu", "Sigmoid", "LeakyRelu", "Softsign"])
def test_numpy_agrees_with_onnxruntime_on_random_inputs(tmp_path: Path, activation: str) -> None:
    pytest.importorskip("onnxruntime", reason="the comparison needs onnxruntime")
    rng = np.random.default_rng(7)
    model = mlp_model(
        _random_mlp(rng, (128, 128, 128, 128)),  # Playground's 4 × 128
        activation,
        obs_mean=rng.normal(size=OBSERVATION_SIZE),
        obs_std=rng.uniform(0.1, 2.0, OBSERVATION_SIZE),
        metadata=deploy_metadata(50.0, 0.3, P_GAINS),
    )
    path = _save(model, tmp_path / "mlp.onnx")
    ort_run, _, ort_engine = load_onnx(path, "onnxruntime")
    np_run, meta, np_engine = load_onnx(path, "numpy")
    assert (ort_engine, np_engine) == ("onnxruntime", "numpy")
    worst = 0.0
    for _ in range(200):
        x = rng.normal(0, 3, OBSERVATION_SIZE).astype(np.float32)
        a, b = ort_run(x), np_run(x)
        assert a.shape == b.shape == (N_JOINTS,)
        worst = max(worst, float(np.max(np.abs(a - b))))
    print(f"{activation}: worst |numpy − onnxruntime| {worst:.2e}")
    assert worst < 1e-5
    # Not all clipped: the comparison saw the network's own numbers.
    assert np.mean(np.abs(np_run(x)) < 1.0) > 0.2
    assert contract_mismatch(meta) == ""


def test_a_gemm_with_transposed_weights_and_a_matmul_add_graph_agree(tmp_path: Path) -> None:
    pytest.importorskip("onnxruntime", reason="the comparison needs onnxruntime")
    rng = np.random.default_rng(3)
    w1 = rng.normal(size=(64, OBSERVATION_SIZE)).astype(np.float32)  # (out, in): transB
    w2 = rng.normal(size=(64, N_JOINTS)).astype(np.float32)
    graph = helper.make_graph(
        [
            helper.make_node("Gemm", ["obs", "w1", "b1"], ["h"], transB=1, alpha=0.5, beta=2.0),
            helper.make_node("Elu", ["h"], ["e"], alpha=0.7),
            helper.make_node("MatMul", ["e", "w2"], ["m"]),
            helper.make_node("Add", ["m", "b2"], ["action"]),
        ],
        "g",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, [1, OBSERVATION_SIZE])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, [1, N_JOINTS])],
        [
            numpy_helper.from_array(w1, "w1"),
            numpy_helper.from_array(rng.normal(size=64).astype(np.float32), "b1"),
            numpy_helper.from_array(w2, "w2"),
            numpy_helper.from_array(rng.normal(size=N_JOINTS).astype(np.float32), "b2"),
        ],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    path = _save(model, tmp_path / "g.onnx")
    ort_run, _, _ = load_onnx(path, "onnxruntime")
    np_run, _, _ = load_onnx(path, "numpy")
    x = rng.normal(size=OBSERVATION_SIZE).astype(np.float32)
    np.testing.assert_allclose(np_run(x), ort_run(x), rtol=1e-5, atol=1e-5)


def test_a_graph_with_an_operator_it_cannot_evaluate_is_refused_naming_it(tmp_path: Path) -> None:
    model = mlp_model(_random_mlp(np.random.default_rng(1), (16,)), "Tanh",
                      metadata=deploy_metadata(50.0, 0.3, P_GAINS))  # fmt: skip
    node = model.graph.node[1]  # the hidden activation
    node.op_type = "Softmax"
    path = _save(model, tmp_path / "softmax.onnx")
    with pytest.raises(PolicyLoadError, match=r"operator Softmax .* not one the numpy runner"):
        NumpyGraph(onnx.load(path), path)
    res = subprocess.run(
        [sys.executable, "-m", "robot_daemon.launch.cli", "policy", "run", path, "--sim",
         "--engine", "numpy", "--seconds", "1"],
        capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL,
    )  # fmt: skip
    assert res.returncode == 1 and "Traceback" not in res.stderr
    (line,) = res.stderr.strip().splitlines()
    assert "operator Softmax" in line and "install onnxruntime" in line


def _model_with(tmp_path: Path, name: str, **changes: str) -> str:
    meta = deploy_metadata(50.0, 0.3, P_GAINS)
    meta.update(changes)
    model = mlp_model(_random_mlp(np.random.default_rng(2), (16,)), "Tanh", metadata=meta)
    return _save(model, tmp_path / name)


def test_a_model_for_another_contract_is_refused_naming_the_mismatch(tmp_path: Path) -> None:
    swapped = list(JOINT_NAMES)
    swapped[12], swapped[13] = swapped[13], swapped[12]
    cases = {
        "version.onnx": ({META_SCHEMA: "99"}, "contract schema version 99"),
        "joints.onnx": (
            {META_JOINTS: json.dumps(swapped)},
            f"joint order differs: joint 12 is {swapped[12]}, the contract's is {JOINT_NAMES[12]}",
        ),
        "layout.onnx": (
            {"darwin.observation_layout": json.dumps([["gravity", 3], ["gyro", 3]])},
            "observation layout",
        ),
    }
    for name, (changes, why) in cases.items():
        path = _model_with(tmp_path, name, **changes)
        for engine in ("auto", "numpy"):
            with pytest.raises(PolicyLoadError, match="refused") as err:
                load_policy(path, engine)
            assert why in str(err.value), err.value
    # One line from the command, naming it.
    path = _model_with(tmp_path, "cli.onnx", **{META_SCHEMA: "99"})
    res = subprocess.run(
        [sys.executable, "-m", "robot_daemon.launch.cli", "policy", "run", path, "--sim"],
        capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL,
    )  # fmt: skip
    assert res.returncode == 1 and res.stderr.count("\n") == 1, res.stderr
    assert "contract schema version 99, this one is 1" in res.stderr
    # A model without deploy constants says what it lacks.
    bare = mlp_model(_random_mlp(np.random.default_rng(2), (16,)), "Tanh")
    with pytest.raises(PolicyLoadError, match=r"no darwin\.schema_version metadata"):
        load_policy(_save(bare, tmp_path / "bare.onnx"))


def test_the_daemons_reply_is_checked_too() -> None:
    meta = deploy_metadata(50.0, 0.3, P_GAINS)
    from schemas.policy import DEFAULT_POSE

    daemon = {"joints": list(JOINT_NAMES), "default_pose": list(DEFAULT_POSE), "scale": 0.3}
    assert contract_mismatch(meta, daemon) == ""
    assert "the daemon applies 0.25" in contract_mismatch(meta, {**daemon, "scale": 0.25})
    moved = list(DEFAULT_POSE)
    moved[3] += 0.1
    why = contract_mismatch(meta, {**daemon, "default_pose": moved})
    assert why.startswith(f"its default pose differs at {JOINT_NAMES[3]}")


def test_the_numpy_engine_runs_a_policy_in_the_simulator(tmp_path: Path) -> None:
    # Zero weights: the policy holds the stand pose, and stands.
    layers = [(np.zeros((OBSERVATION_SIZE, 8)), np.zeros(8)), (np.zeros((8, N_JOINTS)),
              np.zeros(N_JOINTS))]  # fmt: skip
    path = _save(mlp_model(layers, "Relu", metadata=deploy_metadata(25.0, 0.3, P_GAINS)),
                 tmp_path / "zero.onnx")  # fmt: skip
    policy, rate = load_policy(path, "numpy")
    assert rate == 25.0 and policy.engine == "numpy"  # type: ignore[attr-defined]
    assert run_sim(policy, 25.0, 1.0, 0.0, 0) == 25


SHIPPED = Path(__file__).resolve().parents[2] / "clients" / "learn" / "policies" / "stand_push.onnx"


def test_the_shipped_policy_carries_this_contracts_constants() -> None:
    from config.loader import load_all, load_robot
    from robot_daemon.motion.policy import PolicySettings
    from schemas.joints import JOINT_IDS

    model = onnx.load(str(SHIPPED))
    meta = {p.key: p.value for p in model.metadata_props}
    assert contract_mismatch(meta) == ""
    robot = load_robot()
    assert json.loads(meta["darwin.p_gains"]) == [robot.by_id[j].p for j in JOINT_IDS]
    assert float(meta["rate_hz"]) == 50.0
    training = json.loads(meta["darwin.training"])
    # Made at the action scale it carries, one the daemon's `policy` op=start takes (0.01-1 rad
    # per unit; the config's 0.3 where the file says nothing else).
    scale = float(meta["darwin.action_scale"])
    configured = PolicySettings.from_config(load_all().get("policy")).scale
    assert scale == (training["settings"].get("scale") or configured)
    assert 0.01 <= scale <= 1.0
    # Random search of a linear reflex (clients/learn/train.py --method ars), probed on the
    # full model as the push table shoves: it stood 1.0 N·s each way there.
    assert training["algorithm"].startswith("ARS") and "reflex" in training
    assert set(training["probe"]) == {"impulses", "forward", "backward"}
    assert training["probe"]["forward"][0] == training["probe"]["backward"][0] == 1
    # The stance centred on the line every stance trades forward against backward along
    # (docs/learning.md): its probe, read as the loaded stack reads, stood 1.2 N·s both ways,
    # where the crouch shipped before stood forward 1.0 only.
    probe = training["probe"]
    assert probe["impulses"][1] == 1.2 and probe["forward"][1] == probe["backward"][1] == 1
    # …at the offsets its log's command gives (action units at its scale; the reflex keeps
    # them scaled by ARS_SCALES["stance"]), the same numbers the page's command shows.
    command = SHIPPED.with_suffix(".log").read_text().splitlines()[0].split()
    at = command.index("--stance")
    stance = [float(x) for x in command[at + 1 : at + 5]]
    assert np.allclose(training["reflex"]["stance"], np.array(stance) * ARS_SCALES["stance"])
    assert f"--scale {scale:g}" in " ".join(command)
    # What numpy runs is what was trained: every operator is one the robot can evaluate.
    assert {n.op_type for n in model.graph.node} <= set(SUPPORTED_OPS)
    policy, _ = load_policy(str(SHIPPED), "numpy")
    assert policy(np.zeros(OBSERVATION_SIZE, np.float32)).shape == (N_JOINTS,)
    # The log beside it says how it was made.
    log = SHIPPED.with_suffix(".log").read_text().splitlines()
    assert log[0].startswith("training: python -m clients.learn.train ")
    assert log[-1].startswith("policy: clients/learn/policies/stand_push.onnx")
