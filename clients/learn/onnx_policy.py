"""ONNX policies: the deploy constants a model carries, and a numpy evaluator for the robot.

A policy file says what it was trained for in its ``metadata_props`` (kinfer's and LeRobot's
practice: the constants travel with the weights), under ``darwin.*`` keys: the contract's schema
version, the joint order, the default pose, the observation layout, the action mode and scale,
the rate (``rate_hz``, read before these keys existed too) and the P gains it was trained at.
:func:`contract_mismatch` compares them with the contract this program speaks
(schemas/policy.py, the daemon's too: a message of another schema version does not decode) and
with the daemon's ``policy`` op=start reply; a model for another contract is refused, naming the
mismatch.

The robot's computer (Debian 12 i386) has no onnxruntime (no 32-bit wheel, no Debian package)
but ships ``python3-onnx``: :class:`NumpyGraph` evaluates the graph's nodes in numpy (float32,
the operators an MLP policy is made of: MatMul, Gemm, Add/Sub/Mul/Div, the usual activations,
Clip, Reshape...). A graph with any other operator is refused in one line naming it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from schemas.errors import DarwinError
from schemas.joints import JOINT_NAMES
from schemas.policy import (
    CONTRACT_VERSION,
    DEFAULT_POSE,
    N_JOINTS,
    OBSERVATION_LAYOUT,
    OBSERVATION_SIZE,
)


class PolicyLoadError(DarwinError):
    """The policy file cannot be loaded (the message names the cause and the fix)."""


# -- deploy constants -----------------------------------------------------------------------
META_SCHEMA = "darwin.schema_version"
META_JOINTS = "darwin.joints"
META_DEFAULT_POSE = "darwin.default_pose"
META_LAYOUT = "darwin.observation_layout"
META_MODE = "darwin.action_mode"
META_SCALE = "darwin.action_scale"
META_P_GAINS = "darwin.p_gains"
META_RATE = "rate_hz"
POSE_TOL = 1e-4  # rad: the default pose as written in JSON and read back


def deploy_metadata(
    rate_hz: float, scale: float, p_gains: Sequence[int], **extra: str
) -> dict[str, str]:
    """The ``metadata_props`` of a policy trained against this contract."""
    return {
        META_SCHEMA: str(CONTRACT_VERSION),
        META_JOINTS: json.dumps(list(JOINT_NAMES)),
        META_DEFAULT_POSE: json.dumps([round(v, 6) for v in DEFAULT_POSE]),
        META_LAYOUT: json.dumps([[n, k] for n, k in OBSERVATION_LAYOUT]),
        META_MODE: "offset",
        META_SCALE: repr(float(scale)),
        META_P_GAINS: json.dumps([int(p) for p in p_gains]),
        META_RATE: repr(float(rate_hz)),
        **extra,
    }


def contract_mismatch(meta: dict[str, str], daemon: dict[str, Any] | None = None) -> str:
    """What in the model's metadata differs from this contract (and, given the daemon's
    ``policy`` op=start reply, from the daemon's); "" when nothing does."""
    if META_SCHEMA not in meta:
        return (
            f"it has no {META_SCHEMA} metadata (a model made for this contract carries "
            "clients.learn.onnx_policy.deploy_metadata())"
        )
    if meta[META_SCHEMA] != str(CONTRACT_VERSION):
        return (
            f"it is for contract schema version {meta[META_SCHEMA]}, this one is {CONTRACT_VERSION}"
        )
    try:
        joints = json.loads(meta[META_JOINTS])
        pose = json.loads(meta[META_DEFAULT_POSE])
        layout = [tuple(x) for x in json.loads(meta[META_LAYOUT])]
        mode = meta.get(META_MODE, "offset")
        scale = float(meta[META_SCALE])
    except (KeyError, ValueError, TypeError) as exc:
        return f"its deploy metadata is incomplete or unreadable ({type(exc).__name__}: {exc})"
    want_joints = list(daemon["joints"]) if daemon else list(JOINT_NAMES)
    if joints != want_joints:
        pairs = enumerate(zip(joints, want_joints, strict=False))  # may differ in length
        k = next((i for i, (a, b) in pairs if a != b), min(len(joints), len(want_joints)))
        got = joints[k] if k < len(joints) else "nothing"
        want = want_joints[k] if k < len(want_joints) else "nothing"
        return f"its joint order differs: joint {k} is {got}, the contract's is {want}"
    if layout != [(n, k) for n, k in OBSERVATION_LAYOUT]:
        return f"its observation layout {layout} is not the contract's {list(OBSERVATION_LAYOUT)}"
    want_pose = list(daemon["default_pose"]) if daemon else list(DEFAULT_POSE)
    diff = [abs(a - b) for a, b in zip(pose, want_pose, strict=False)]
    if len(pose) != len(want_pose) or max(diff) > POSE_TOL:
        k = int(np.argmax(diff)) if diff else 0
        return (
            f"its default pose differs at {want_joints[k]}: "
            f"{pose[k] if k < len(pose) else None} rad, the contract's {want_pose[k]:.6f}"
        )
    if mode != "offset":
        return f"its action mode is {mode!r}; the runner streams offset actions"
    if daemon is not None and not math.isclose(float(daemon["scale"]), scale, rel_tol=1e-6):
        return f"its action scale is {scale:g} rad, the daemon applies {daemon['scale']:g}"
    return ""


# -- the numpy evaluator ----------------------------------------------------------------------
def _attrs(node: Any) -> dict[str, Any]:
    from onnx import helper

    return {a.name: helper.get_attribute_value(a) for a in node.attribute}


def _gemm(x: list[np.ndarray], a: dict[str, Any]) -> np.ndarray:
    m, w = x[0], x[1]
    if a.get("transA", 0):
        m = m.T
    if a.get("transB", 0):
        w = w.T
    y = np.float32(a.get("alpha", 1.0)) * (m @ w)
    if len(x) > 2 and x[2] is not None:
        y = y + np.float32(a.get("beta", 1.0)) * x[2]
    return y


def _clip(x: list[np.ndarray], a: dict[str, Any]) -> np.ndarray:
    lo = x[1] if len(x) > 1 and x[1] is not None else a.get("min")
    hi = x[2] if len(x) > 2 and x[2] is not None else a.get("max")
    return np.clip(x[0], lo, hi)


def _elu(v: np.ndarray, alpha: float) -> np.ndarray:
    return np.where(v > 0, v, np.float32(alpha) * np.expm1(np.minimum(v, 0))).astype(np.float32)


def _sigmoid(v: np.ndarray) -> np.ndarray:
    return (1.0 / (1.0 + np.exp(-v))).astype(np.float32)


_OPS: dict[str, Callable[[list[np.ndarray], dict[str, Any]], np.ndarray]] = {
    "MatMul": lambda x, a: x[0] @ x[1],
    "Gemm": _gemm,
    "Add": lambda x, a: x[0] + x[1],
    "Sub": lambda x, a: x[0] - x[1],
    "Mul": lambda x, a: x[0] * x[1],
    "Div": lambda x, a: x[0] / x[1],
    "Neg": lambda x, a: -x[0],
    "Relu": lambda x, a: np.maximum(x[0], np.float32(0)),
    "LeakyRelu": lambda x, a: np.where(x[0] > 0, x[0], np.float32(a.get("alpha", 0.01)) * x[0]),
    "Elu": lambda x, a: _elu(x[0], a.get("alpha", 1.0)),
    "Selu": lambda x, a: (
        np.float32(a.get("gamma", 1.0507009873554805))
        * _elu(x[0], a.get("alpha", 1.6732632423543772))
    ),
    "Tanh": lambda x, a: np.tanh(x[0]),
    "Sigmoid": lambda x, a: _sigmoid(x[0]),
    "Softplus": lambda x, a: np.logaddexp(np.float32(0), x[0]).astype(np.float32),
    "Softsign": lambda x, a: x[0] / (np.float32(1) + np.abs(x[0])),
    "Clip": _clip,
    "Identity": lambda x, a: x[0],
    "Reshape": lambda x, a: x[0].reshape([int(d) for d in x[1]]),
    "Flatten": lambda x, a: x[0].reshape(int(np.prod(x[0].shape[: a.get("axis", 1)])), -1),
    "Squeeze": lambda x, a: np.squeeze(
        x[0], axis=tuple(int(v) for v in (x[1] if len(x) > 1 else a.get("axes", ()))) or None
    ),
    "Unsqueeze": lambda x, a: np.expand_dims(
        x[0], tuple(int(v) for v in (x[1] if len(x) > 1 else a["axes"]))
    ),
    "Cast": lambda x, a: x[0].astype(np.float32),
}
SUPPORTED_OPS = tuple(sorted(_OPS))


class NumpyGraph:
    """An ONNX graph evaluated node by node in numpy, float32."""

    def __init__(self, model: Any, path: str = "the model") -> None:
        from onnx import numpy_helper

        g = model.graph
        for node in g.node:
            if node.op_type not in _OPS and node.op_type != "Constant":
                raise PolicyLoadError(
                    f"{path}: operator {node.op_type} (node {node.name or node.output[0]}) is "
                    f"not one the numpy runner evaluates ({', '.join(SUPPORTED_OPS)}); "
                    "install onnxruntime to run it"
                )
        self.consts: dict[str, np.ndarray] = {
            t.name: numpy_helper.to_array(t) for t in g.initializer
        }
        for k, v in self.consts.items():
            if v.dtype.kind == "f":
                self.consts[k] = v.astype(np.float32)
        self.nodes = [(n.op_type, list(n.input), list(n.output), _attrs(n)) for n in g.node]
        for op, _, out, a in self.nodes:
            if op == "Constant":
                self.consts[out[0]] = np.asarray(numpy_helper.to_array(a["value"]))
        self.nodes = [n for n in self.nodes if n[0] != "Constant"]
        inputs = [i.name for i in g.input if i.name not in self.consts]
        if len(inputs) != 1 or len(g.output) != 1:
            raise PolicyLoadError(
                f"{path} has {len(inputs)} inputs and {len(g.output)} outputs; a policy has one "
                "of each (the observation, the action)"
            )
        self.input = inputs[0]
        self.output = g.output[0].name
        dims = g.input[[i.name for i in g.input].index(self.input)].type.tensor_type.shape.dim
        self.input_size = dims[-1].dim_value if dims and dims[-1].dim_value else None

    def __call__(self, x: np.ndarray) -> np.ndarray:
        values = dict(self.consts)
        values[self.input] = np.asarray(x, np.float32)
        for op, ins, outs, a in self.nodes:
            args = [values[i] if i else None for i in ins]
            # An absent optional input is None, which each operator checks for itself.
            values[outs[0]] = np.asarray(_OPS[op](args, a))  # type: ignore[arg-type]
        return values[self.output]


def load_onnx(
    path: str, engine: str = "auto"
) -> tuple[Callable[[np.ndarray], np.ndarray], dict[str, str], str]:
    """The policy of an ``.onnx`` file, its metadata and the engine that runs it
    (``onnxruntime`` where installed and ``engine`` allows, else ``numpy``)."""
    import os

    if not os.path.isfile(path):
        raise PolicyLoadError(f"{path} does not exist")
    ort: Any = None
    if engine in ("auto", "onnxruntime"):
        try:
            import onnxruntime

            ort = onnxruntime
        except ImportError:
            if engine == "onnxruntime":
                raise PolicyLoadError(
                    "onnxruntime is not installed: pip install -e '.[learn]'"
                ) from None
    model: Any = None
    try:
        import onnx
    except ImportError:
        if ort is None:
            raise PolicyLoadError(
                "ONNX policies need onnx (apt install python3-onnx on the robot) or onnxruntime "
                "(pip install -e '.[learn]')"
            ) from None
    else:
        try:
            model = onnx.load(path)
        except Exception as exc:  # protobuf's DecodeError and friends
            raise PolicyLoadError(f"{path} is not a loadable ONNX model: {exc}") from None
    if ort is None:
        graph = NumpyGraph(model, path)
        meta = {p.key: p.value for p in model.metadata_props}
        size = graph.input_size
        run_graph: Callable[[np.ndarray], np.ndarray] = graph
        used = "numpy"
    else:
        try:
            session = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own unrelated types
            raise PolicyLoadError(f"{path} is not a loadable ONNX model: {exc}") from None
        inp = session.get_inputs()[0]
        size = inp.shape[-1] if isinstance(inp.shape[-1], int) else None
        meta = dict(session.get_modelmeta().custom_metadata_map)
        name = inp.name

        def run_graph(x: np.ndarray) -> np.ndarray:
            return np.asarray(session.run(None, {name: x})[0])

        used = "onnxruntime"
    if size not in (OBSERVATION_SIZE, None):
        raise PolicyLoadError(f"{path} takes {size} inputs; the observation has {OBSERVATION_SIZE}")

    def run(obs: np.ndarray) -> np.ndarray:
        x = np.asarray(obs, np.float32).reshape(1, OBSERVATION_SIZE)
        return run_graph(x).reshape(-1)

    return run, meta, used


# -- writing a policy -------------------------------------------------------------------------
def mlp_model(
    layers: Sequence[tuple[np.ndarray, np.ndarray]],
    activation: str = "Tanh",
    obs_mean: np.ndarray | None = None,
    obs_std: np.ndarray | None = None,
    metadata: dict[str, str] | None = None,
    out_map: np.ndarray | None = None,
) -> Any:
    """An ONNX model of an MLP policy from its weights (``(W [in, out], b [out])`` per layer,
    ``activation`` between them, none after the last), the observation normalised first, the
    outputs mapped to the 20 joints by ``out_map`` (``[outputs, 20]``) when given, the action
    clipped to ±1: built with ``onnx.helper``, no torch needed."""
    from onnx import TensorProto, helper, numpy_helper

    nodes, inits = [], []
    x = "obs"
    if obs_mean is not None and obs_std is not None:
        inits += [
            numpy_helper.from_array(np.asarray(obs_mean, np.float32), "obs_mean"),
            numpy_helper.from_array(
                (1.0 / np.asarray(obs_std, np.float32)).astype(np.float32), "obs_inv_std"
            ),
        ]
        nodes += [
            helper.make_node("Sub", [x, "obs_mean"], ["centred"]),
            helper.make_node("Mul", ["centred", "obs_inv_std"], ["normalised"]),
        ]
        x = "normalised"
    for k, (w, b) in enumerate(layers):
        inits += [
            numpy_helper.from_array(np.asarray(w, np.float32), f"w{k}"),
            numpy_helper.from_array(np.asarray(b, np.float32), f"b{k}"),
        ]
        nodes.append(helper.make_node("Gemm", [x, f"w{k}", f"b{k}"], [f"h{k}"]))
        x = f"h{k}"
        if k < len(layers) - 1:
            nodes.append(helper.make_node(activation, [x], [f"a{k}"]))
            x = f"a{k}"
    if out_map is not None:  # the network's outputs → the 20 joints' actions
        inits.append(numpy_helper.from_array(np.asarray(out_map, np.float32), "out_map"))
        nodes.append(helper.make_node("MatMul", [x, "out_map"], ["joints"]))
        x = "joints"
    inits += [
        numpy_helper.from_array(np.array(-1.0, np.float32), "lo"),
        numpy_helper.from_array(np.array(1.0, np.float32), "hi"),
    ]
    nodes.append(helper.make_node("Clip", [x, "lo", "hi"], ["action"]))
    graph = helper.make_graph(
        nodes,
        "darwin_policy",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, [1, OBSERVATION_SIZE])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, [1, N_JOINTS])],
        inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)],
                              producer_name="darwin-zenoh")  # fmt: skip
    model.ir_version = 8  # read by onnx 1.10+ and onnxruntime 1.10+
    if metadata:
        helper.set_model_props(model, metadata)
    return model
