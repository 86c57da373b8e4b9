"""The trainer's random search (clients/learn/train.py, ``--method ars``): the copy of the
hand-made controller it starts from stands what that controller stands, a generation writes an
ONNX file that computes what the search's policy computes, with the contract's constants."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from clients.learn import train
from clients.learn.examples.stand_balance import StandBalance
from clients.learn.runner import load_policy
from schemas.policy import OBSERVATION_SIZE

pytest.importorskip("onnx", reason="writing the policy needs the onnx package")


def test_the_search_starts_from_the_hand_made_controller_on_its_features() -> None:
    agent = train.Search(train.SearchSettings(), seed=0)
    agent.copy_stand_balance()
    teacher = StandBalance()
    # The training model, nominal: a shove each way that the hand-made controller stands.
    copied = train.shoved(agent.deterministic, (1.0,))
    taught = train.shoved(teacher, (1.0,), reset=teacher.reset)
    assert copied == taught == [[train.SHOVE_STEPS, train.SHOVE_STEPS]]


def test_a_generation_writes_the_policy_it_searched(tmp_path: Path) -> None:
    out = tmp_path / "reflex.onnx"
    s = train.SearchSettings(directions=2, top=1, episodes=2, probe_every=1, after=0.5)
    agent = train.search(s, seed=0, generations=1, out=out)
    policy, rate = load_policy(str(out), "numpy")
    assert rate == train.RATE
    rng = np.random.default_rng(1)
    for _ in range(5):
        obs = rng.normal(0, 0.3, OBSERVATION_SIZE).astype(np.float32)
        np.testing.assert_allclose(policy(obs), agent.deterministic(obs), atol=1e-5)
    import onnx

    meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    made = json.loads(meta["darwin.training"])
    assert made["algorithm"].startswith("ARS") and made["generations"] == 1
    assert set(made["probe"]) == {"impulses", "forward", "backward"}
