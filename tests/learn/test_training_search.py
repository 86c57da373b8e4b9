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


def test_a_search_goes_on_from_the_reflex_it_wrote_and_refuses_another_file(
    tmp_path: Path,
) -> None:
    out = tmp_path / "reflex.onnx"
    s = train.SearchSettings(directions=2, top=1, episodes=2, probe_every=1, after=0.5,
                             impulse_weight=1.0, hold=(1, 3), balance=True)  # fmt: skip
    first = train.search(s, seed=0, generations=1, out=out)
    # Each direction's shoves spread over its own range (the weight is against its middle).
    fresh = train.Search(train.SearchSettings(), seed=0)  # forward 0.9–1.5, backward 1.2–1.8
    assert list(fresh.impulses(4)) == pytest.approx([1.05, -1.35, 1.35, -1.65])
    again = train.Search(train.SearchSettings(search="tilt"), seed=5)
    again.start_from(out)
    np.testing.assert_array_equal(again.m, first.m)
    other = tmp_path / "mlp.onnx"
    from clients.learn.onnx_policy import deploy_metadata, mlp_model
    from tests.learn.test_onnx_policy import P_GAINS

    w = np.zeros((OBSERVATION_SIZE, 20))
    import onnx

    onnx.save(mlp_model([(w, np.zeros(20))], "Relu", metadata=deploy_metadata(50.0, 0.3, P_GAINS)),
              str(other))  # fmt: skip
    with pytest.raises(ValueError, match="not a reflex written by --method ars"):
        again.start_from(other)


def test_held_sensor_readings_repeat_for_at_most_the_hold_and_the_last_action_never() -> None:
    """``Randomization.hold``: a loaded stack's joint and IMU readings hold for 2–4 steps; the
    fast backend holds them for 1..hi steps, never its own last action."""
    import gymnasium as gym

    import clients.learn.env  # noqa: F401
    from clients.learn.fast import Randomization
    from schemas.policy import OBSERVATION_SLICES as at

    def runs(hold: tuple[int, int]) -> tuple[list[int], int]:
        rnd = Randomization.off()
        rnd.hold = hold
        env = gym.make("darwin/Stand-v0", randomize=rnd)
        obs, _ = env.reset(seed=3)
        lengths, fresh_actions, prev, n = [], 0, obs, 1
        sensors = ("gyro", "gravity", "joint_pos", "joint_vel")  # all held together
        for k in range(60):  # an arm swing: the joints move every step
            a = np.zeros(20)
            a[0], a[1] = np.sin(k / 5), -np.sin(k / 5)
            obs, *_ = env.step(a)
            fresh_actions += not np.array_equal(obs[at["last_action"]], prev[at["last_action"]])
            if all(np.array_equal(obs[at[f]], prev[at[f]]) for f in sensors):
                n += 1
            else:
                lengths.append(n)
                n = 1
            prev = obs
        env.close()
        return lengths, fresh_actions

    held, fresh = runs((3, 3))
    assert max(held) == 3 and min(held) >= 1 and sum(h > 1 for h in held) >= 5
    assert fresh >= 55  # the daemon's own last action is never stale
    never, _ = runs((1, 1))
    assert set(never) == {1}


def test_the_tilt_is_split_at_its_zero_and_the_written_file_splits_it_there(
    tmp_path: Path,
) -> None:
    """``tilt_zero``: the tilt's two sides meet at the stand pose's lean, not at upright, so
    a backward shove (the lean falling from its rest toward upright) takes the backward rows."""
    from schemas.policy import OBSERVATION_SLICES as at

    s = train.SearchSettings(search="tilt", tilt_zero=0.2)
    agent = train.Search(s, seed=0)
    n, ankle = len(agent.names), list(s.pairs).index("ankle_pitch")
    agent.m[agent.names.index("gravity_x"), ankle] = 0.1  # forward of the zero: this row
    agent.m[n + agent.split.index(agent.names.index("gravity_x")), ankle] = 0.0  # behind: none
    r_ankle = int(np.flatnonzero(agent.out_map[ankle])[0])

    def ankle_at(policy, gravity_x: float) -> float:  # type: ignore[no-untyped-def]
        obs = np.zeros(OBSERVATION_SIZE, np.float32)
        obs[at["gravity"]] = (gravity_x, 0.0, -1.0)
        return float(policy(obs)[r_ankle])

    # Upright and at 0.15 are behind a zero of 0.2: no answer (split at 0 they were forward).
    assert [ankle_at(agent.deterministic, g) for g in (0.0, 0.15, 0.2)] == pytest.approx(
        [0.0, 0.0, 0.0], abs=1e-6)
    assert abs(ankle_at(agent.deterministic, 0.3)) == pytest.approx(0.1, abs=1e-6)
    out = tmp_path / "reflex.onnx"
    train.export_linear(agent, out, {"generations": 0})
    policy, _ = load_policy(str(out), "numpy")
    for g in (-0.1, 0.0, 0.15, 0.2, 0.25, 0.4):
        assert ankle_at(policy, g) == pytest.approx(ankle_at(agent.deterministic, g), abs=1e-5)


def test_the_probe_reads_as_the_loaded_stack_when_asked_and_a_start_keeps_its_tilt_zero(
    tmp_path: Path,
) -> None:
    """``probe_hold``: the probe's full model holds its readings (and has latency and IMU
    noise) as the loaded stack does; nominal otherwise. A file searched at one tilt zero is not
    gone on from at another (its tilt rows would answer other tilts)."""
    s = train.SearchSettings(search="tilt", probe_hold=(3, 3), tilt_zero=0.1)
    agent = train.Search(s, seed=0)
    for probe_hold, latency in (((3, 3), (0.0, 0.01)), ((1, 1), (0.0, 0.0))):
        train._WORKER.clear()
        train._init_worker(agent.out_map, "latency", (1, 1), probe_hold)
        rnd = train._worker_env(False).unwrapped.backend.random
        assert (rnd.hold, rnd.latency) == (probe_hold, latency)
    train._WORKER.clear()
    out = tmp_path / "reflex.onnx"
    train.export_linear(agent, out, {"generations": 0})
    train.Search(s, seed=1).start_from(out)  # the same zero
    with pytest.raises(ValueError, match=r"splits the tilt at 0\.1, this search at 0: give"):
        train.Search(train.SearchSettings(search="tilt"), seed=1).start_from(out)


def test_the_stance_is_an_offset_per_pair_the_search_moves_and_the_written_file_keeps(
    tmp_path: Path,
) -> None:
    """``stance``: a constant feature whose row is each pair's offset, the pose the reflex
    rests in (its crouch and lean), searched with the rest; a file searched without it goes
    on with none; without it the search's rows, and so its random draws, are as before."""
    plain = train.Search(train.SearchSettings(search="tilt"), seed=0)
    assert "stance" not in plain.names
    s = train.SearchSettings(search="tilt", stance=True)
    agent = train.Search(s, seed=0)
    k = agent.names.index("stance")
    assert agent.m.shape == (plain.m.shape[0] + 1, plain.m.shape[1])
    assert agent.mask[k].tolist() == [1.0] * len(s.pairs)  # searched, for every pair
    offset = np.array([0.0, -0.5, 1.0, 0.2])  # a crouch, the ankles back: pair units
    agent.m[k] = offset * train.ARS_SCALES["stance"]
    rest = np.zeros(OBSERVATION_SIZE)
    np.testing.assert_allclose(agent.deterministic(rest), offset @ agent.out_map, atol=1e-12)
    out = tmp_path / "stance.onnx"
    train.export_linear(agent, out, {"generations": 0})
    policy, _ = load_policy(str(out), "numpy")
    rng = np.random.default_rng(2)
    for obs in [rest, *rng.normal(0, 0.3, (4, OBSERVATION_SIZE))]:
        np.testing.assert_allclose(policy(obs.astype(np.float32)), agent.deterministic(obs),
                                   atol=1e-5)  # fmt: skip
    again = train.Search(s, seed=1)
    again.start_from(out)
    np.testing.assert_array_equal(again.m, agent.m)
    # A reflex written without the stance: the same rows, no offset yet.
    plain.m[:] = rng.normal(0, 0.1, plain.m.shape)
    old = tmp_path / "plain.onnx"
    train.export_linear(plain, old, {"generations": 0})
    grown = train.Search(s, seed=1)
    grown.start_from(old)
    assert grown.m[k].tolist() == [0.0] * len(s.pairs)
    np.testing.assert_array_equal(np.delete(grown.m, k, axis=0), plain.m)
    for obs in rng.normal(0, 0.3, (4, OBSERVATION_SIZE)):
        np.testing.assert_allclose(grown.deterministic(obs), plain.deterministic(obs), atol=1e-12)
    with pytest.raises(ValueError, match="reads other features"):
        train.Search(train.SearchSettings(search="tilt"), seed=1).start_from(out)


def test_a_stance_search_starts_at_the_offsets_given_and_refuses_a_count_of_another_pairs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "stance.onnx"
    s = train.SearchSettings(search="tilt", stance=True, directions=1, top=1, episodes=2,
                             probe_every=1, after=0.5, noise=0.0)  # fmt: skip
    agent = train.search(s, seed=0, generations=1, out=out, stance=(0.0, -0.5, 1.0, 0.2))
    row = agent.m[agent.names.index("stance")] / train.ARS_SCALES["stance"]
    assert row.tolist() == pytest.approx([0.0, -0.5, 1.0, 0.2])  # no noise: not moved
    with pytest.raises(SystemExit):
        train.main(["--method", "ars", "--stance", "1", "2", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.endswith("--stance takes an offset for each of the 4 pairs (shoulder_pitch, "
                        "hip_pitch, knee, ankle_pitch), not 2")  # fmt: skip


def test_a_search_from_a_file_keeps_it_until_a_generation_probes_as_well(tmp_path: Path) -> None:
    """The start (a file, or offsets given) is probed before the first generation: a search
    that only gets worse writes the start, not its best worse probe."""
    start = tmp_path / "start.onnx"
    copy = train.Search(train.SearchSettings(search="tilt"), seed=0)
    copy.copy_stand_balance()  # stands 1.0 N·s each way on the full model (test above)
    train.export_linear(copy, start, {"generations": 0})
    wild = train.SearchSettings(search="tilt", directions=1, top=1, episodes=2, probe_every=1,
                                after=0.5, noise=2.0, step=50.0)  # fmt: skip
    out = tmp_path / "kept.onnx"
    lines: list[str] = []

    class Log:
        def write(self, text: str) -> None:
            lines.extend(t for t in text.splitlines() if t.startswith("probe"))

        def flush(self) -> None: ...

    agent = train.search(wild, seed=0, generations=1, out=out, log=Log(), start=start)
    assert lines[0].startswith("probe 0: stood forward 1+") and "backward 1+" in lines[0]
    assert lines[0].endswith("(best so far, written)")
    assert lines[1].startswith("probe 1: ") and "best" not in lines[1]  # the wild step fell
    np.testing.assert_array_equal(agent.m, copy.m)
    import onnx

    made = json.loads({p.key: p.value for p in onnx.load(str(out)).metadata_props}
                      ["darwin.training"])  # fmt: skip
    assert made["generations"] == 0 and made["trained_generations"] == 1


def test_a_search_at_another_action_scale_goes_on_from_the_same_reflex_in_rad(
    tmp_path: Path,
) -> None:
    """``scale``: the worlds step at it and the file carries it (``darwin policy run`` starts
    the stream at it); a file of another scale is the same reflex in rad, its rows but the
    last actions' (action units to action units) scaled, its offsets too."""
    import onnx

    from schemas.policy import OBSERVATION_SLICES as at

    s = train.SearchSettings(search="tilt", stance=True)
    old = train.Search(s, seed=0)
    rng = np.random.default_rng(4)
    old.m[:] = rng.normal(0, 0.05, old.m.shape) * old.mask
    old.m[old.names.index("stance")] = np.array([0.0, -0.2, 0.4, 0.1]) * train.ARS_SCALES["stance"]
    start = tmp_path / "at_0.3.onnx"
    train.export_linear(old, start, {"generations": 0})
    wide = train.SearchSettings(search="tilt", stance=True, scale=0.9)
    agent = train.Search(wide, seed=1)
    agent.start_from(start)
    for obs in rng.normal(0, 0.2, (5, OBSERVATION_SIZE)):
        here = obs.copy()
        here[at["last_action"]] *= 0.3 / 0.9  # the same targets, in this scale's units
        np.testing.assert_allclose(0.9 * agent.deterministic(here), 0.3 * old.deterministic(obs),
                                   atol=1e-12)  # fmt: skip
    out = tmp_path / "at_0.9.onnx"
    train.export_linear(agent, out, {"generations": 0})
    meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    assert float(meta["darwin.action_scale"]) == 0.9
    train._WORKER.clear()
    train._init_worker(agent.out_map, "latency", (1, 1), (2, 4), 0.9)
    assert train._worker_env(False).unwrapped.backend.scale == 0.9
    train._WORKER.clear()


def test_the_probe_kept_is_the_largest_shove_stood_when_asked(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``rank``: "weaker" keeps the probe with most impulses stood in the weaker direction,
    "largest" the one that stands the largest shove with 1.0 N·s stood both ways (the push
    table's bar: larger shoves than both baselines, none worse); ``generations`` 0 writes the
    start, probed."""
    probes = iter([
        ([1, 0, 0, 0, 0, 0], [1, 1, 1, 1, 0, 0]),  # the start: forward 1.0, backward 1.6
        ([1, 1, 0, 0, 0, 0], [1, 1, 0, 0, 0, 0]),  # 1.2 each way
        ([0, 0, 0, 0, 0, 0], [1, 1, 1, 1, 1, 1]),  # backward 2.0, no forward shove
    ] * 2)  # fmt: skip
    monkeypatch.setattr(train.Search, "probe", lambda self, pool, impulses: next(probes))
    monkeypatch.setattr(train.Search, "generation", lambda self, pool: (
        {"score": 0.0, "stood": 0.0, "forward": (1.0, 1.5), "backward": (1.0, 1.5)}))
    start = tmp_path / "start.onnx"
    train.export_linear(train.Search(train.SearchSettings(search="tilt"), seed=0), start,
                        {"generations": 0})  # fmt: skip
    kept = {}
    for rank in ("weaker", "largest"):
        s = train.SearchSettings(search="tilt", probe_every=1, rank=rank)
        out = tmp_path / f"{rank}.onnx"
        train.search(s, seed=0, generations=2, out=out, start=start)
        import onnx

        meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
        kept[rank] = json.loads(meta["darwin.training"])["generations"]
    assert kept == {"weaker": 1, "largest": 0}
    monkeypatch.setattr(train.Search, "probe", lambda self, pool, impulses: (
        [1, 0, 0, 0, 0, 0], [1, 1, 0, 0, 0, 0]))
    out = tmp_path / "start_only.onnx"
    train.search(train.SearchSettings(search="tilt"), seed=0, generations=0, out=out, start=start)
    import onnx

    made = json.loads({p.key: p.value for p in onnx.load(str(out)).metadata_props}
                      ["darwin.training"])  # fmt: skip
    assert made["generations"] == 0 and made["trained_generations"] == 0
