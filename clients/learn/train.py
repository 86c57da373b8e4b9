"""Train a stand-under-pushes policy on the fast backend and write it as an ONNX file.

    python -m clients.learn.train --out policies/stand_push.onnx --minutes 25 --seed 0

PPO (clipped surrogate, GAE, Adam) written here in numpy against ``darwin/Stand-v0``, not a
library: the networks are two small MLPs whose gradients take a page, the simulation costs far
more than the learning, and numpy is what the robot already has; a library (Stable-Baselines3,
skrl, rsl_rl) brings torch, gigabytes where a CUDA build is the default. The environment is
Gymnasium's vector API over the fast backend (``gym.make_vec``: ``--envs`` worlds in this
process), with MuJoCo Playground's domain randomisation (:class:`Randomization`: floor friction,
joint friction, armature, masses, Kp, damping; plus latency and IMU noise) and shoves of
``--push`` N·s every 1–3 s. Everything is seeded by ``--seed``: the same command writes the same
file (on the same numpy and MuJoCo builds).

The file is the deterministic policy (the Gaussian's mean), the observation normaliser in front
and the action clipped to ±1, with the deploy constants in its metadata
(:func:`clients.learn.onnx_policy.deploy_metadata`) and how it was made (``darwin.training``).
Each iteration prints one line: steps, mean return and length of the episodes that ended.

``--method ars`` searches a linear reflex instead (:func:`search`: random search scored on the
shoves stood, docs/learning.md says why); it writes the same kind of file.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from schemas.joints import JOINT_NAMES
from schemas.policy import N_JOINTS, OBSERVATION_SIZE

RATE = 50.0


# -- networks ---------------------------------------------------------------------------------
class MLP:
    """Tanh hidden layers, a linear output; ``backward`` after ``forward`` on the same batch."""

    def __init__(self, sizes: Sequence[int], rng: np.random.Generator, out_gain: float) -> None:
        self.params: list[np.ndarray] = []
        for k, (n_in, n_out) in enumerate(itertools.pairwise(sizes)):
            gain = out_gain if k == len(sizes) - 2 else math.sqrt(2)
            # Orthogonal initialisation, as PPO implementations do.
            a = rng.normal(size=(max(n_in, n_out), min(n_in, n_out)))
            q, r = np.linalg.qr(a)
            q = q * np.sign(np.diag(r))
            w = (q if n_in >= n_out else q.T)[:n_in, :n_out] * gain
            self.params += [w.astype(np.float64), np.zeros(n_out)]
        self._cache: list[np.ndarray] = []

    @property
    def layers(self) -> list[tuple[np.ndarray, np.ndarray]]:
        return [(self.params[i], self.params[i + 1]) for i in range(0, len(self.params), 2)]

    def forward(self, x: np.ndarray) -> np.ndarray:
        self._cache = [x]
        n = len(self.params) // 2
        for k in range(n):
            x = x @ self.params[2 * k] + self.params[2 * k + 1]
            if k < n - 1:
                x = np.tanh(x)
            self._cache.append(x)
        return x

    def backward(self, grad: np.ndarray) -> list[np.ndarray]:
        n = len(self.params) // 2
        grads: list[np.ndarray] = [np.empty(0)] * len(self.params)
        for k in reversed(range(n)):
            if k < n - 1:
                grad = grad * (1.0 - self._cache[k + 1] ** 2)
            grads[2 * k] = self._cache[k].T @ grad
            grads[2 * k + 1] = grad.sum(axis=0)
            grad = grad @ self.params[2 * k].T
        return grads


class Adam:
    def __init__(self, params: list[np.ndarray], lr: float) -> None:
        self.params, self.lr, self.t = params, lr, 0
        self.m = [np.zeros_like(p) for p in params]
        self.v = [np.zeros_like(p) for p in params]

    def step(self, grads: list[np.ndarray], max_norm: float = 0.5) -> None:
        norm = math.sqrt(sum(float(np.sum(g * g)) for g in grads))
        scale = min(1.0, max_norm / (norm + 1e-8))
        self.t += 1
        b1, b2 = 0.9, 0.999
        for p, g, m, v in zip(self.params, grads, self.m, self.v, strict=True):
            g = g * scale
            m *= b1
            m += (1 - b1) * g
            v *= b2
            v += (1 - b2) * g * g
            mh = m / (1 - b1**self.t)
            vh = v / (1 - b2**self.t)
            p -= self.lr * mh / (np.sqrt(vh) + 1e-8)


class Normaliser:
    """Running mean and variance of the observations (Welford, batched)."""

    def __init__(self, n: int) -> None:
        self.mean, self.var, self.count = np.zeros(n), np.ones(n), 1e-4

    def update(self, x: np.ndarray) -> None:
        bm, bv, bc = x.mean(axis=0), x.var(axis=0), len(x)
        delta, total = bm - self.mean, self.count + bc
        self.mean = self.mean + delta * bc / total
        m2 = self.var * self.count + bv * bc + delta**2 * self.count * bc / total
        self.var, self.count = m2 / total, total

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(self.var) + 1e-2  # never amplify a constant input (command, …) wildly

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return (x - self.mean) / self.std


@dataclass
class Settings:
    """The PPO run's settings: worlds, horizon, optimiser, exploration and the policy's outputs."""

    envs: int = 32  # more worlds, the same 1,024 steps an iteration: more shoves in each
    horizon: int = 32  # steps per env per iteration
    epochs: int = 4
    minibatches: int = 4
    lr: float = 2e-4  # fine-tuning a copied controller: small steps
    gamma: float = 0.99
    lam: float = 0.95
    clip: float = 0.2
    # Exploration (action units): 0.15 (0.045 rad) found nothing the copied controller did not
    # already do; the better answers to a shove differ from it by tenths.
    init_std: float = 0.25
    # The policy's own outputs, each driving a left/right pair of servos mirrored (the pair's
    # directions are mirrored: +u on the right is −u on the left, as stand_balance.py's ankles):
    # the sagittal joints a push along x is answered with. () = all 20 joints, one each.
    pairs: tuple[str, ...] = ("shoulder_pitch", "hip_pitch", "knee", "ankle_pitch")
    imitate_steps: int = 6000  # warm start: steps of stand_balance.py under pushes to copy
    value_warmup: int = 3  # iterations that train the value function alone, the policy kept
    hidden: tuple[int, ...] = (128, 128)
    # N·s. Where the answer matters: on the nominal model holding the stand takes ~1.0 forward
    # and ~1.5 backward, the hand-made controller ~1.2 both ways, and nothing that keeps its
    # feet planted takes 1.8 (docs/learning.md); shoves outside that teach nothing (all
    # survive, or all fall).
    push: tuple[float, float] = (1.0, 1.7)
    push_back: tuple[float, float] | None = None  # backward shoves' range, if not ``push``
    push_spread: float = 0.2  # rad about forward/backward (the push table shoves along x)
    # Short episodes, a shove 1–2 s in (and maybe one more): each episode is about one shove,
    # not the luck of a series of them (400-step episodes with shoves every 1–3 s gave returns
    # too noisy to learn from in 150 iterations).
    push_every: tuple[float, float] = (1.0, 2.0)
    episode_steps: int = 150
    randomize: bool = True
    sweep: bool = True  # after a probed run: the full model's shove table, in the log
    reward_scale: float = 0.1  # returns of ~20, not ~200: the value net's targets near 1
    # Every this many iterations the deterministic policy is shoved as the push table does
    # (:func:`shoved`, the nominal full model) and the file keeps the best so far: PPO's
    # policy wanders between iterations, and the last one is not the best one.
    probe_every: int = 10


def action_map(pairs: Sequence[str]) -> np.ndarray:
    """``[len(pairs), 20]``: the policy's outputs → the contract's 20-joint action."""
    if not pairs:
        return np.eye(N_JOINTS)
    m = np.zeros((len(pairs), N_JOINTS))
    for i, joint in enumerate(pairs):
        m[i, JOINT_NAMES.index(f"r_{joint}")] = 1.0
        m[i, JOINT_NAMES.index(f"l_{joint}")] = -1.0
    return m


class PPO:
    def __init__(self, s: Settings, seed: int) -> None:
        self.s = s
        self.best: tuple[int, int] = (-1, -1)  # (shoves stood, steps stood) of the probe
        self.best_made: dict[str, Any] = {}
        self._best_params: list[np.ndarray] = []
        self.rng = np.random.default_rng(seed)
        self.out_map = action_map(s.pairs)
        n_out = len(self.out_map)
        sizes = (OBSERVATION_SIZE, *s.hidden)
        # A near-zero first action: the untrained policy holds the stand pose.
        self.pi = MLP((*sizes, n_out), self.rng, out_gain=0.01)
        self.vf = MLP((*sizes, 1), self.rng, out_gain=1.0)
        self.log_std = np.full(n_out, math.log(s.init_std))
        self.norm = Normaliser(OBSERVATION_SIZE)
        self.opt = Adam([*self.pi.params, self.log_std, *self.vf.params], s.lr)

    def act(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        x = self.norm(obs)
        mu = self.pi.forward(x)
        std = np.exp(self.log_std)
        a = mu + std * self.rng.normal(size=mu.shape)
        return a, self._logp(a, mu), self.vf.forward(x)[:, 0], x

    def deterministic(self, obs: np.ndarray) -> np.ndarray:
        """The policy the file holds: the mean action, clipped."""
        mu = self.pi.forward(self.norm(np.asarray(obs, float)[None]))[0]
        return np.clip(mu @ self.out_map, -1.0, 1.0)

    def keep_best(self, made: dict[str, Any]) -> None:
        self.best_made = made
        self._best_params = [p.copy() for p in self.pi.params]

    def restore_best(self) -> None:
        for p, kept in zip(self.pi.params, self._best_params, strict=True):
            p[...] = kept

    def value(self, obs: np.ndarray) -> np.ndarray:
        return self.vf.forward(self.norm(obs))[:, 0]

    def _logp(self, a: np.ndarray, mu: np.ndarray) -> np.ndarray:
        z = (a - mu) / np.exp(self.log_std)
        k = len(self.log_std)
        return -0.5 * np.sum(z * z, axis=1) - np.sum(self.log_std) - 0.5 * k * math.log(2 * math.pi)

    def imitate(self, envs: Any, steps: int, log: Any) -> None:
        """Warm start: fit the policy's mean to stand_balance.py's answers (its ankle output
        on the ankle pair) on observations of it balancing under the same shoves."""
        from clients.learn.examples.stand_balance import L_ANKLE, R_ANKLE, StandBalance

        ankle = int(np.flatnonzero(self.out_map[:, R_ANKLE])[0])
        teachers = [StandBalance() for _ in range(envs.num_envs)]
        obs, _ = envs.reset(seed=int(self.rng.integers(2**31)))
        xs, ys = [], []
        for _ in range(steps // envs.num_envs):
            acts = np.stack([t(o) for t, o in zip(teachers, obs, strict=True)])
            target = np.zeros((len(obs), len(self.out_map)))
            target[:, ankle] = acts[:, R_ANKLE]
            assert np.allclose(acts[:, L_ANKLE], -acts[:, R_ANKLE])
            xs.append(obs.copy())
            ys.append(target)
            obs, _, term, trunc, _ = envs.step(acts)
            for i in np.flatnonzero(term | trunc):
                teachers[i].reset()
        x, y = np.concatenate(xs), np.concatenate(ys)
        self.norm.update(x)
        xn = self.norm(x)
        opt = Adam(self.pi.params, 1e-3)
        for _ in range(60):
            order = self.rng.permutation(len(x))
            for k in range(0, len(x), 256):
                idx = order[k : k + 256]
                mu = self.pi.forward(xn[idx])
                opt.step(self.pi.backward((mu - y[idx]) / len(idx)), max_norm=10.0)
        err = float(np.mean((self.pi.forward(xn) - y) ** 2))
        print(
            f"imitation: {len(x)} steps of stand_balance.py, mean squared error {err:.5f} "
            f"(its output variance {float(np.var(y[:, ankle])):.5f})",
            file=log,
            flush=True,
        )

    def update(self, x, a, logp_old, adv, ret, policy: bool = True) -> dict[str, float]:
        s, n = self.s, len(x)
        size = n // s.minibatches
        stats: dict[str, float] = {"clipfrac": 0.0, "vloss": 0.0}
        for _ in range(s.epochs):
            order = self.rng.permutation(n)
            for k in range(s.minibatches):
                idx = order[k * size : (k + 1) * size]
                xb, ab, lb = x[idx], a[idx], logp_old[idx]
                advb = (adv[idx] - adv[idx].mean()) / (adv[idx].std() + 1e-8)
                mu = self.pi.forward(xb)
                std = np.exp(self.log_std)
                logp = self._logp(ab, mu)
                ratio = np.exp(logp - lb)
                active = ~(
                    ((advb > 0) & (ratio > 1 + s.clip)) | ((advb < 0) & (ratio < 1 - s.clip))
                )
                d_logp = -(ratio * advb * active) / len(idx)  # d loss / d logp
                d_mu = d_logp[:, None] * (ab - mu) / std**2
                d_log_std = np.sum(d_logp[:, None] * (((ab - mu) / std) ** 2 - 1.0), axis=0)
                g_pi = self.pi.backward(d_mu)
                if not policy:  # the value function learns first: its advantages are noise
                    g_pi = [np.zeros_like(g) for g in g_pi]
                    d_log_std = np.zeros_like(d_log_std)
                v = self.vf.forward(xb)[:, 0]
                d_v = (v - ret[idx]) / len(idx)  # 0.5 (v − R)² averaged
                g_vf = self.vf.backward(d_v[:, None])
                self.opt.step([*g_pi, d_log_std, *g_vf])
                stats["clipfrac"] += float(np.mean(~active)) / (s.epochs * s.minibatches)
                stats["vloss"] += float(np.mean((v - ret[idx]) ** 2)) / (s.epochs * s.minibatches)
        return stats


def make_envs(s: Settings, seed: int) -> Any:
    import gymnasium as gym

    import clients.learn.env  # noqa: F401  (registers darwin/Stand-v0)
    from clients.learn.fast import Randomization

    envs = gym.make_vec(
        "darwin/Stand-v0",
        num_envs=s.envs,
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": gym.vector.AutoresetMode.SAME_STEP},
        randomize=Randomization() if s.randomize else Randomization.off(),
        pushes=s.push,
        push_every=s.push_every,
        pushes_back=s.push_back,
        push_spread=s.push_spread,
        max_steps=s.episode_steps,
    )
    envs.reset(seed=seed)
    return envs


def train(
    s: Settings,
    seed: int,
    iterations: int,
    minutes: float = 0.0,
    out: Path | None = None,
    log: Any = sys.stdout,
) -> tuple[PPO, list[float]]:
    """Train; returns the agent and the mean return of the episodes that ended in each
    iteration (nan where none did)."""
    envs = make_envs(s, seed)
    agent = PPO(s, seed)
    before = evaluate(agent)
    if s.imitate_steps:
        agent.imitate(envs, s.imitate_steps, log)
    obs, _ = envs.reset(seed=seed)
    ep_ret, ep_len = np.zeros(s.envs), np.zeros(s.envs, int)
    returns: list[float] = []
    t0 = time.monotonic()
    steps = 0
    for it in range(iterations):
        if not s.imitate_steps:
            # A copied policy keeps the normaliser it was fitted with: moving it would move
            # the policy with no gradient step at all.
            agent.norm.update(obs)
        buf_x, buf_a, buf_l, buf_r, buf_v, buf_d = [], [], [], [], [], []
        done_ret, done_len = [], []
        for _ in range(s.horizon):
            a, logp, v, x = agent.act(obs)
            obs, r, term, trunc, info = envs.step(a @ agent.out_map)
            ep_ret += r
            ep_len += 1
            r = np.asarray(r, float) * s.reward_scale
            if trunc.any():  # bootstrap a cut-off episode from its last observation
                final = np.stack([info["final_obs"][i] if t else obs[i]
                                  for i, t in enumerate(trunc)])  # fmt: skip
                r = r + s.gamma * agent.value(final) * (trunc & ~term)
            for i in np.flatnonzero(term | trunc):
                done_ret.append(ep_ret[i])
                done_len.append(ep_len[i])
                ep_ret[i], ep_len[i] = 0.0, 0
            buf_x.append(x)
            buf_a.append(a)
            buf_l.append(logp)
            buf_r.append(r)
            buf_v.append(v)
            buf_d.append((term | trunc).astype(float))
            steps += s.envs
        last_v = agent.value(obs)
        rew, val, dones = np.array(buf_r), np.array(buf_v), np.array(buf_d)
        adv = np.zeros_like(rew)
        gae = np.zeros(s.envs)
        for t in reversed(range(s.horizon)):
            nxt = last_v if t == s.horizon - 1 else val[t + 1]
            delta = rew[t] + s.gamma * nxt * (1 - dones[t]) - val[t]
            gae = delta + s.gamma * s.lam * (1 - dones[t]) * gae
            adv[t] = gae
        ret = adv + val
        stats = agent.update(
            np.concatenate(buf_x), np.concatenate(buf_a), np.concatenate(buf_l),
            adv.reshape(-1), ret.reshape(-1), policy=it >= s.value_warmup,
        )  # fmt: skip
        mean_ret = float(np.mean(done_ret)) if done_ret else math.nan
        returns.append(mean_ret)
        elapsed = time.monotonic() - t0
        print(
            f"iter {it + 1} steps {steps} return {mean_ret:.1f} length "
            f"{float(np.mean(done_len)) if done_len else math.nan:.0f} episodes {len(done_ret)} "
            f"std {float(np.exp(agent.log_std).mean()):.3f} clipfrac {stats['clipfrac']:.2f} "
            f"vloss {stats['vloss']:.2f} elapsed {elapsed:.0f} s",
            file=log, flush=True,
        )  # fmt: skip
        if it + 1 >= s.value_warmup and (it + 1) % s.probe_every == 0:
            # On the stack's full model: the push table's plant, not the one trained on.
            after_shove = [n for row in shoved(agent.deterministic, PROBE_IMPULSES, fast=False)
                           for n in row]  # fmt: skip
            score = (sum(n >= SHOVE_STEPS for n in after_shove), sum(after_shove))
            print(f"probe {it + 1}: stood {score[0]} of {2 * len(PROBE_IMPULSES)} shoves of "
                  f"{', '.join(f'{i:g}' for i in PROBE_IMPULSES)} N·s forward and backward"
                  f"{' (best so far, written)' if score >= agent.best else ''}",
                  file=log, flush=True)  # fmt: skip
            if score >= agent.best:  # a tie goes to the longer-trained policy
                agent.best = score
                agent.keep_best(
                    {
                        "iterations": it + 1,
                        "steps": steps,
                        "probe": {
                            "impulses": PROBE_IMPULSES,
                            "stood": score[0],
                            "steps_stood": score[1],
                        },
                    }
                )
                if out is not None:  # a stopped run leaves its best so far
                    export(agent, out, agent.best_made)
        if minutes and elapsed > minutes * 60:
            break
    envs.close()
    made: dict[str, Any] = {"iterations": len(returns), "steps": steps}
    if agent.best >= (0, 0):  # the best probed checkpoint is the result: evaluate that one
        agent.restore_best()
        made = {**agent.best_made, "trained_iterations": len(returns), "trained_steps": steps}
        if s.sweep:  # a run long enough to be probed is shoved once more, in full
            print_sweep(agent, log)
    after = evaluate(agent)
    print(f"evaluation return (1.0 N·s shoves, 4 seeded episodes): untrained {before:.1f}, "
          f"trained {after:.1f}", file=log, flush=True)  # fmt: skip
    if out is not None:
        export(agent, out, {**made, "evaluation": {"untrained": before, "trained": after}})
    return agent, returns


PROBE_IMPULSES = (1.2, 1.4, 1.6)
SWEEP_IMPULSES = (1.0, 1.2, 1.4, 1.6, 1.8)
SHOVE_AT = 1.5  # s after the settled start, as benchmarks/push_table.py shoves
SHOVE_RUN = 5.0  # s an episode lasts, as the push table's `darwin policy run --seconds 5`
SHOVE_STEPS = int(SHOVE_RUN * RATE) - int(SHOVE_AT * RATE)  # steps from the shove to the end


def shoved(
    policy: Any, impulses: Sequence[float], fast: bool = True, reset: Any = None
) -> list[list[int]]:
    """The push table's protocol on the nominal model (no randomisation): for each impulse a
    shove forward then backward (+x, −x, 0.1 s at the torso) ``SHOVE_AT`` s into a settled
    start; per shove, the steps it stood after it (``SHOVE_RUN`` s in all: all of them is
    standing). ``fast=False``: the stack's full model."""
    import gymnasium as gym

    import clients.learn.env  # noqa: F401
    from clients.learn.env import PUSH_S
    from clients.learn.fast import Randomization

    at, total = int(SHOVE_AT * RATE), int(SHOVE_RUN * RATE)
    env = gym.make("darwin/Stand-v0", randomize=Randomization.off(), max_steps=total, fast=fast)
    table = []
    for impulse in impulses:
        row = []
        for sign in (1.0, -1.0):
            obs, _ = env.reset(seed=0)
            if reset is not None:
                reset()
            k = 0
            for k in range(total):
                if k == at:
                    env.unwrapped.push((sign * impulse / PUSH_S, 0.0, 0.0), PUSH_S)  # type: ignore[attr-defined]
                obs, _, term, _, _ = env.step(policy(obs))
                if term:
                    break
            row.append(k + 1 - at if term else total - at)
        table.append(row)
    env.close()
    return table


def print_sweep(agent: PPO, log: Any, impulses: Sequence[float] = SWEEP_IMPULSES) -> None:
    """Which shoves each policy stands on the stack's full model (fast backend, nominal)."""
    from clients.learn.examples.stand_balance import StandBalance, hold

    teacher = StandBalance()
    print("shoves stood on the full model (forward/backward; the push table's protocol):",
          file=log, flush=True)  # fmt: skip
    policies = [("trained", agent.deterministic, None),
                ("stand_balance", teacher, teacher.reset), ("hold", hold, None)]  # fmt: skip
    for name, policy, reset in policies:
        table = shoved(policy, impulses, fast=False, reset=reset)
        cells = ", ".join(
            f"{i:g} {'/'.join('up' if n >= SHOVE_STEPS else 'fell' for n in row)}"
            for i, row in zip(impulses, table, strict=True)
        )
        print(f"  {name}: {cells}", file=log, flush=True)


def evaluate(agent: PPO, impulse: float = 1.0, episodes: int = 4, steps: int = 150) -> float:
    """Mean return of the deterministic policy (the mean action) on the nominal training model,
    shoved ``impulse`` N·s forward or backward 1 s into each seeded episode."""
    import gymnasium as gym

    import clients.learn.env  # noqa: F401
    from clients.learn.fast import Randomization

    env = gym.make("darwin/Stand-v0", randomize=Randomization.off(), max_steps=steps)
    total = 0.0
    for seed in range(episodes):
        obs, _ = env.reset(seed=seed)
        for k in range(steps):
            if k == int(RATE):
                sign = 1.0 if seed % 2 == 0 else -1.0
                env.unwrapped.push((sign * impulse / 0.1, 0.0, 0.0), 0.1)  # type: ignore[attr-defined]
            mu = agent.pi.forward(agent.norm(obs[None].astype(float)))[0]
            obs, r, term, trunc, _ = env.step(np.clip(mu @ agent.out_map, -1.0, 1.0))
            total += float(r)
            if term or trunc:
                break
    env.close()
    return total / episodes


def export(agent: PPO, out: Path, made: dict[str, Any]) -> None:
    """The deterministic policy as ONNX, with its deploy constants (written atomically)."""
    import onnx

    from clients.learn.onnx_policy import deploy_metadata, mlp_model
    from config.loader import load_all, load_robot
    from robot_daemon.motion.policy import PolicySettings
    from schemas.joints import JOINT_IDS

    robot = load_robot()
    scale = PolicySettings.from_config(load_all().get("policy")).scale
    training = {"algorithm": "PPO (numpy, clients/learn/train.py)", **made,
                "settings": {k: v for k, v in vars(agent.s).items()}}  # fmt: skip
    meta = deploy_metadata(RATE, scale, [robot.by_id[j].p for j in JOINT_IDS],
                           **{"darwin.training": json.dumps(training)})  # fmt: skip
    model = mlp_model(agent.pi.layers, "Tanh", agent.norm.mean, agent.norm.std, meta,
                      out_map=agent.out_map)  # fmt: skip
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".onnx.tmp")
    onnx.save(model, str(tmp))
    tmp.replace(out)



# -- augmented random search: a linear reflex, scored on the shoves themselves ----------------
# PPO fine-tuning the copied controller (above) learnt a stance, not a reflex: its reward pays
# ~2 a step for staying alive and ~0.01 for the pose, and a shove is one step in 150. Random
# search (Mania, Guy & Recht 2018, "Simple random search provides a competitive approach to
# reinforcement learning": ARS V1-t) scores each candidate on what the push table asks, the
# shoves stood, and needs no value function: a linear map from the sagittal state to the four
# mirrored pairs, 56 numbers, which is what a standing reflex (ankle and hip strategy) is.
ARS_SCALES = {"gravity": 0.1, "gyro": 1.0, "joint_pos": 0.1, "joint_vel": 1.0, "last_action": 1.0,
              "stance": 0.2}


def ars_features(pairs: Sequence[str]) -> tuple[np.ndarray, list[str]]:
    """``[69, n]``: the observation → the features the reflex reads, each scaled to ~1: the
    gravity's x (tilt forward), the pitch rate, and per pair the position, velocity and last
    action, (right − left) / 2 (the pairs are mirrored)."""
    from schemas.policy import OBSERVATION_SLICES as at

    cols, names = [], []

    def col(entries: dict[int, float], name: str) -> None:
        c = np.zeros(OBSERVATION_SIZE)
        for i, v in entries.items():
            c[i] = v
        cols.append(c)
        names.append(name)

    col({at["gravity"].start: 1 / ARS_SCALES["gravity"]}, "gravity_x")
    col({at["gyro"].start + 1: 1 / ARS_SCALES["gyro"]}, "pitch_rate")
    for field in ("joint_pos", "joint_vel", "last_action"):
        for joint in pairs:
            r = at[field].start + JOINT_NAMES.index(f"r_{joint}")
            lft = at[field].start + JOINT_NAMES.index(f"l_{joint}")
            k = 0.5 / ARS_SCALES[field]
            col({r: k, lft: -k}, f"{field}.{joint}")
    return np.stack(cols, axis=1), names


@dataclass
class SearchSettings:
    """The random search over the linear map: which numbers it perturbs, how far and how many."""

    pairs: tuple[str, ...] = Settings.pairs
    directions: int = 6  # perturbations per generation (each tried + and −)
    top: int = 3  # the best directions the step follows
    # Perturbation std per feature (action units per scaled unit): 0.03 threw the copied
    # controller over before most shoves (a tilt fed to the hips is a loop through the torso).
    noise: float = 0.02
    step: float = 0.02
    # Which of the map's numbers are searched: "reflex" (each pair's answer to the tilt and
    # the pitch rate, and its own position, velocity and last action: 20 numbers) or "all"
    # (56: every feature to every pair). On a shared machine a generation of the 56 took
    # 15–90 s and 10 of them moved nothing: the cross terms add noise faster than signal.
    search: str = "reflex"
    episodes: int = 8  # per candidate: half shoved forward, half backward, the same for ±δ
    # N·s of the shoves forward and backward, each direction's range following the policy (a
    # curriculum): while the candidates stand more than ``raise_at`` of that direction's
    # shoves it moves up 0.1 (to ``push_max`` at most), under ``lower_at`` down 0.1: a range
    # where every candidate falls, or every one stands, scores them all alike and teaches
    # nothing. Forward starts lower: the robot takes less that way.
    push: tuple[float, float] = (0.9, 1.5)
    push_back: tuple[float, float] = (1.2, 1.8)
    push_max: float = 2.4
    raise_at: float = 0.7
    lower_at: float = 0.3
    shove_at: float = 0.5  # s into a settled start
    after: float = 2.5  # s run after the shove
    pose_weight: float = 1.0  # per rad of RMS pose error, averaged over the episode
    probe_every: int = 5
    workers: int = 1
    # "playground": MuJoCo Playground OP3's domain randomisation (:class:`Randomization`);
    # "latency": only what the simulated stack has that the nominal model lacks (0–10 ms of
    # action latency, IMU noise). The push table's stack is the nominal model: worlds of low
    # floor friction and soft servos where no candidate stands a shove score all alike.
    randomize: str = "playground"
    # Policy steps a sensor reading may hold in the training worlds (Randomization.hold):
    # (1, 1) never; the loaded stack's readings hold 2–4 (docs/learning.md).
    hold: tuple[int, int] = (1, 1)
    # An episode's score × (impulse / the middle of its direction's range) ** this: the larger
    # shoves of each range count more (0: all alike), as the push table asks for the largest
    # stood. Against the middle of its own range, not 1 N·s: a weight on the impulse itself
    # let the backward shoves (the larger range) outweigh the forward ones, and the search
    # traded forward for backward (forward 1.4 stood at generation 15, nothing at 30).
    impulse_weight: float = 0.0
    # A candidate's score is that of its weaker direction (the mean of its forward shoves' or
    # of its backward shoves', the lower), not the mean of all: on the mean the search traded
    # one direction for the other from probe to probe (forward 1.4 N·s stood, then backward
    # 1.8 and forward not 1.0), where the push table, and the probe, ask for both.
    balance: bool = False
    # The gravity's x at which the tilt is split into its two sides (its zero), not 0: the
    # stand pose leans forward, and holding it the gravity filter reads 0.22 at rest, so a
    # tilt split at upright answers a backward shove (the lean falling from 0.22 to 0) with
    # the rows of a forward one. Holding the stand stands 1.4 N·s backward where a reflex
    # that rests upright (the shipped file, 0.12) does not: its answer to a backward shove
    # was worse than none, and the search could not learn "none" on a split at 0.
    tilt_zero: float = 0.0
    # The probe's world: (1, 1) the nominal full model; (lo, hi) the full model with its
    # readings held lo..hi steps, 0–10 ms of latency and IMU noise, each shove on two seeds
    # (stood: both). The nominal model ranked files the stack did not (a file that stood
    # forward 1.4 N·s there fell 3 of 3 forward shoves of 1.0 on the stack); held 2–4 it
    # gave all three rows of the stack's one-run table (docs/learning.md).
    probe_hold: tuple[int, int] = (1, 1)
    # A constant feature (1 / ARS_SCALES["stance"]) each pair answers with an offset of its
    # own, searched with the rest: the pose the reflex rests in, its crouch and its lean. With
    # the feet planted what a shove each way takes is set by where the body rests over the
    # feet more than by the answer (docs/learning.md: a reflex without its forward rows rested
    # leaning further forward and stood backward shoves, and no forward one; the stand page
    # held, its knees bent 0.3 rad more and its ankles 0.09 rad back, stood 1.2 N·s either
    # way on the full model read as the loaded stack, where the page itself stands 1.4
    # backward and no forward 1.0). Off, the search's numbers and random draws are those of
    # the runs before it (the shipped file's command makes the same file).
    stance: bool = False
    # rad per action unit (0: the config's ``[policy] scale``, 0.3, MuJoCo Playground's), the
    # deploy constant the file carries and ``darwin policy run`` starts the stream at. A crouch
    # takes most of a pair's ±1 at 0.3 (the knee rested at 0.85 of it, and its answer to a
    # forward shove was clipped); at a larger scale the same reflex in rad keeps its answer.
    scale: float = 0.0
    # Which probe the file keeps: "weaker" most impulses stood in the weaker direction, then
    # in both; "largest" the smallest shove (1.0 N·s) stood both ways, then the largest shove
    # stood either way, then the weaker direction's. The push table asks the second: a
    # policy that stands larger shoves than both baselines, none worse. Ranked by the weaker
    # direction, a probe of 1.2 N·s each way beat one of forward 1.0 with backward 1.6, which
    # on the stack falls less at 1.6 N·s (3 of 6) than both baselines (6 of 6).
    rank: str = "weaker"


_WORKER: dict[str, Any] = {}


def action_scale(s: SearchSettings) -> float:
    """rad per action unit of the search's worlds and file: ``s.scale``, else the config's."""
    from config.loader import load_all
    from robot_daemon.motion.policy import PolicySettings

    return s.scale or PolicySettings.from_config(load_all().get("policy")).scale


def _worker_env(fast: bool) -> Any:
    key = f"env{fast}"
    if key not in _WORKER:
        import gymnasium as gym

        import clients.learn.env  # noqa: F401
        from clients.learn.fast import Randomization

        rnd = Randomization.off()
        probe_hold = _WORKER.get("probe_hold", (1, 1))
        if fast and _WORKER.get("randomize", "playground") == "playground":
            rnd = Randomization()
        elif fast or probe_hold != (1, 1):
            rnd.latency, rnd.gyro_noise, rnd.accel_noise = (0.0, 0.01), 0.02, 0.1
        rnd.hold = _WORKER.get("hold", (1, 1)) if fast else probe_hold
        env = gym.make("darwin/Stand-v0", randomize=rnd, max_steps=10**6, fast=fast)
        if _WORKER.get("scale"):
            env.unwrapped.backend.scale = _WORKER["scale"]  # type: ignore[attr-defined]
        _WORKER[key] = env
    return _WORKER[key]


Task = tuple[tuple[np.ndarray, np.ndarray, np.ndarray], int, float, float, float, float, bool]


def _episode(task: Task) -> tuple[float, int]:
    """One shoved episode of the reflex ``w`` (its two layers, :meth:`Search.layers`);
    returns (score, steps stood after the shove)."""
    from clients.learn.env import PUSH_S

    w, seed, force, shove_at, after, pose_weight, fast = task
    out_map = _WORKER["out_map"]
    env = _worker_env(fast)
    obs, _ = env.reset(seed=seed)
    at, total = int(shove_at * RATE), int((shove_at + after) * RATE)
    pos = OBSERVATION_SLICES_JOINT_POS
    pose_err, stood = 0.0, total - at
    for k in range(total):
        if k == at:
            env.unwrapped.push((force, 0.0, 0.0), PUSH_S)
        a = np.clip((np.maximum(obs.astype(float) @ w[0] + w[2], 0.0) @ w[1]) @ out_map, -1, 1)
        obs, _, term, _, _ = env.step(a)
        q = obs[pos].astype(float)
        pose_err += math.sqrt(float(q @ q) / len(q))
        if term:
            stood = max(0, k + 1 - at)
            break
    steps = k + 1
    up = stood >= total - at
    score = (1.0 if up else 0.5 * stood / (total - at)) - pose_weight * pose_err / steps
    return score, stood


def _init_worker(
    out_map: np.ndarray,
    randomize: str = "playground",
    hold: tuple[int, int] = (1, 1),
    probe_hold: tuple[int, int] = (1, 1),
    scale: float = 0.0,
) -> None:
    _WORKER["out_map"] = out_map
    _WORKER["scale"] = scale
    _WORKER["randomize"] = randomize
    _WORKER["hold"] = hold
    _WORKER["probe_hold"] = probe_hold


OBSERVATION_SLICES_JOINT_POS = slice(9, 29)


class Search:
    """ARS V1-t over the linear reflex ``M`` ([features, pairs]); the policy's action is
    ``clip(((obs @ F) @ M) @ out_map, ±1)``."""

    def __init__(self, s: SearchSettings, seed: int) -> None:
        from schemas.policy import OBSERVATION_SLICES

        assert OBSERVATION_SLICES["joint_pos"] == OBSERVATION_SLICES_JOINT_POS
        self.s = s
        self.rng = np.random.default_rng(seed)
        self.out_map = action_map(s.pairs)
        self.features, self.names = ars_features(s.pairs)
        if s.stance:  # a constant: its column reads nothing, its bias (layers) is the value
            self.features = np.concatenate([self.features, np.zeros((OBSERVATION_SIZE, 1))], 1)
            self.names.append("stance")
        # The tilt and the pitch rate are answered on each side of zero by rows of their
        # own: a shove forward and one backward may take different answers (a linear map
        # traded one direction for the other: backward 1.6 N·s stood, forward 1.0 not).
        self.split = [self.names.index("gravity_x"), self.names.index("pitch_rate")]
        n = len(self.names)
        self.m = np.zeros((n + len(self.split), len(s.pairs)))
        self.mask = np.ones_like(self.m)
        if s.search in ("reflex", "tilt"):
            self.mask[:] = 0.0
            self.mask[:2] = 1.0  # the tilt and the pitch rate, to every pair
            self.mask[n:] = 1.0  # and their other side
            # Each pair's own state; "tilt": only its last action, as stand_balance.py reads
            # only the IMU (the stack's joint readings can hold for steps: docs/learning.md).
            own = ("last_action",) if s.search == "tilt" else ("joint_pos", "joint_vel",
                                                              "last_action")  # fmt: skip
            for k, joint in enumerate(s.pairs):
                for field in own:
                    self.mask[self.names.index(f"{field}.{joint}"), k] = 1.0
            if s.stance:
                self.mask[self.names.index("stance")] = 1.0
        self.push = {1.0: s.push, -1.0: s.push_back}
        self.best: tuple[int, ...] = (-1, -1, -1)
        self.best_m = self.m.copy()
        self.best_made: dict[str, Any] = {}

    def copy_stand_balance(self) -> None:
        """Start from stand_balance.py's ankle law, written on these features: its leaky
        integral is the last ankle action kept (×0.95) plus the tilt's and the rate's share."""
        from clients.learn.examples import stand_balance as sb

        ankle = list(self.s.pairs).index("ankle_pitch")
        f = self.names.index
        self.m[f("last_action.ankle_pitch"), ankle] = sb.LEAK
        self.m[f("gravity_x"), ankle] = sb.KI / RATE * ARS_SCALES["gravity"]
        self.m[f("pitch_rate"), ankle] = sb.KD * (1 - sb.LEAK) * ARS_SCALES["gyro"]
        self.m[len(self.names) :] = self.m[self.split]  # the same answer either side

    def start_from(self, path: Path) -> None:
        """Start from a reflex this trainer wrote (its ``darwin.training`` metadata): the
        search goes on from there, with this run's settings."""
        import onnx

        from clients.learn.onnx_policy import META_SCALE

        meta = {p.key: p.value for p in onnx.load(str(path)).metadata_props}
        try:
            made = json.loads(meta["darwin.training"])
            reflex = made["reflex"]
        except (KeyError, ValueError) as exc:
            raise ValueError(f"{path} is not a reflex written by --method ars") from exc
        zero = float(made.get("settings", {}).get("tilt_zero", 0.0))
        if zero != self.s.tilt_zero:  # its tilt rows answer a tilt split elsewhere
            raise ValueError(f"{path}'s reflex splits the tilt at {zero:g}, this search at "
                             f"{self.s.tilt_zero:g}: give --tilt-zero {zero:g}")
        rows = [*self.names, *(f"{self.names[i]}<0" for i in self.split)]
        if self.s.stance and "stance" not in reflex:  # a file searched without: none yet
            reflex = {r: reflex.get(r, [0.0] * len(self.s.pairs)) for r in rows}
        if list(reflex) != rows or np.shape(list(reflex.values())) != self.m.shape:
            raise ValueError(f"{path}'s reflex reads other features or pairs than this search")
        self.m = np.array(list(reflex.values()), dtype=float)
        # A file of another action scale: the same reflex in rad, every row in action units
        # at this scale but the last actions' (action units to action units, as they were).
        ratio = float(meta[META_SCALE]) / action_scale(self.s)
        for k, row in enumerate(rows):
            if not row.startswith("last_action."):
                self.m[k] *= ratio

    def layers(self, m: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The reflex as two layers around a ReLU: [69, 2n] (each feature and its negative)
        and its bias [2n] (the tilt less ``tilt_zero``), [2n, pairs] (a feature's rows (m, −m)
        are linear in it; a split one's are its two sides' own)."""
        m = self.m if m is None else m
        n = len(self.names)
        w1 = np.concatenate([self.features, -self.features], axis=1)
        b1 = np.zeros(2 * n)
        tilt = self.names.index("gravity_x")
        b1[tilt], b1[n + tilt] = np.array([-1.0, 1.0]) * self.s.tilt_zero / ARS_SCALES["gravity"]
        if self.s.stance:  # the constant on its positive side (its negative one reads 0)
            k = self.names.index("stance")
            b1[k], b1[n + k] = np.array([1.0, -1.0]) / ARS_SCALES["stance"]
        w2 = np.concatenate([m[:n], -m[:n]])
        for k, i in enumerate(self.split):
            w2[n + i] = -m[n + k]
        return w1, w2, b1

    def deterministic(self, obs: np.ndarray) -> np.ndarray:
        w1, w2, b1 = self.layers()
        h = np.maximum(np.asarray(obs, float) @ w1 + b1, 0.0)
        return np.clip((h @ w2) @ self.out_map, -1.0, 1.0)

    def impulses(self, n: int) -> np.ndarray:
        """The impulse (N·s, signed) of each of a generation's ``n`` episodes: forward and
        backward in turn, each spread over its direction's range."""
        out = np.empty(n)
        for j in range(n):
            sign = 1.0 if j % 2 == 0 else -1.0
            lo, hi = self.push[sign]
            out[j] = sign * (lo + (hi - lo) * ((j // 2) + 0.5) / max(1, n // 2))
        return out

    def tasks(self, m: np.ndarray, seeds: np.ndarray) -> list[Task]:
        s = self.s
        out = []
        for impulse, seed in zip(self.impulses(len(seeds)), seeds, strict=True):
            out.append((self.layers(m), int(seed), impulse / 0.1, s.shove_at, s.after,
                        s.pose_weight, True))  # fmt: skip
        return out

    def generation(self, pool: Any) -> dict[str, Any]:
        s = self.s
        deltas = self.rng.normal(size=(s.directions, *self.m.shape)) * self.mask
        seeds = self.rng.integers(2**31, size=s.episodes)  # the same episodes for every candidate
        tasks = []
        for d in deltas:
            tasks += self.tasks(self.m + s.noise * d, seeds)
            tasks += self.tasks(self.m - s.noise * d, seeds)
        results = pool.map(_episode, tasks) if pool is not None else list(map(_episode, tasks))
        scores = np.array([r[0] for r in results]).reshape(s.directions, 2, s.episodes)
        if s.impulse_weight:
            impulse = np.abs(self.impulses(s.episodes))
            mid = np.array([sum(self.push[1.0 if j % 2 == 0 else -1.0]) / 2
                            for j in range(s.episodes)])  # fmt: skip
            scores = scores * (impulse / mid) ** s.impulse_weight
        stood = np.array([r[1] for r in results]).reshape(s.directions, 2, s.episodes)
        total = int((s.after) * RATE)
        if s.balance:
            per_way = np.stack([scores[:, :, 0::2].mean(axis=2), scores[:, :, 1::2].mean(axis=2)])
            r_plus, r_minus = per_way.min(axis=0).T
        else:
            r_plus, r_minus = scores[:, 0].mean(axis=1), scores[:, 1].mean(axis=1)
        order = np.argsort(-np.maximum(r_plus, r_minus))[: s.top]
        sigma = float(np.concatenate([r_plus[order], r_minus[order]]).std()) + 1e-6
        step = np.tensordot(r_plus[order] - r_minus[order], deltas[order], axes=1)
        self.m = self.m + s.step / (s.top * sigma) * step
        up = float(np.mean(stood >= total))
        push = dict(self.push)
        for sign, k in ((1.0, 0), (-1.0, 1)):
            lo, hi = self.push[sign]
            frac = float(np.mean(stood[:, :, k::2] >= total))
            if frac > s.raise_at and hi < s.push_max:
                self.push[sign] = (lo + 0.1, hi + 0.1)
            elif frac < s.lower_at and lo > 0.5:
                self.push[sign] = (lo - 0.1, hi - 0.1)
        return {"score": float(scores.mean()), "stood": up, "forward": push[1.0],
                "backward": push[-1.0]}

    def probe(self, pool: Any, impulses: Sequence[float]) -> tuple[list[int], list[int]]:
        """The push table's protocol on the full model (``probe_hold``: nominal, or as the
        loaded stack reads it): per impulse, whether a shove forward and one backward were
        stood (all the steps after the shove, on every seed)."""
        seeds = (0,) if self.s.probe_hold == (1, 1) else (0, 1)
        tasks = [(self.layers(), seed, sign * i / 0.1, SHOVE_AT, SHOVE_RUN - SHOVE_AT, 0.0, False)
                 for i in impulses for sign in (1.0, -1.0) for seed in seeds]  # fmt: skip
        results = pool.map(_episode, tasks) if pool is not None else list(map(_episode, tasks))
        stood = np.array([r[1] >= SHOVE_STEPS for r in results]).reshape(-1, 2, len(seeds))
        up: np.ndarray = np.asarray(stood.all(axis=2))
        return [int(x) for x in up[:, 0]], [int(x) for x in up[:, 1]]


def search(
    s: SearchSettings,
    seed: int,
    generations: int,
    minutes: float = 0.0,
    out: Path | None = None,
    log: Any = sys.stdout,
    imitate: bool = True,
    start: Path | None = None,
    stance: Sequence[float] | None = None,
) -> Search:
    """Random search; every ``probe_every`` generations the policy is shoved on the full model
    as the push table shoves it (1.0–2.0 N·s each way) and the file keeps the best: most
    impulses stood in the weaker direction, then in all, then the later."""
    import multiprocessing

    agent = Search(s, seed)
    if start is not None:
        agent.start_from(start)
    elif imitate:
        agent.copy_stand_balance()
    if stance is not None:  # where the search starts the rest pose: per pair, action units
        agent.m[agent.names.index("stance")] = np.asarray(stance) * ARS_SCALES["stance"]
    ctx = multiprocessing.get_context("fork")
    init = (agent.out_map, s.randomize, s.hold, s.probe_hold, s.scale)
    pool = ctx.Pool(s.workers, _init_worker, init) if s.workers > 1 else None
    _init_worker(*init)
    t0 = time.monotonic()
    impulses = PROBE_SWEEP

    def probe(g: int) -> None:
        fwd, back = agent.probe(pool, impulses)
        weaker, stronger = sorted((sum(fwd), sum(back)))
        if s.rank == "largest":  # the largest shove stood, the smallest stood both ways
            score: tuple[int, ...] = (int(weaker > 0), stronger, weaker, g)
        else:
            score = (weaker, weaker + stronger, g)
        better = score[:-1] >= agent.best[:-1]
        print(f"probe {g}: stood forward {_stood(impulses, fwd)}; backward "
              f"{_stood(impulses, back)}{' (best so far, written)' if better else ''}",
              file=log, flush=True)  # fmt: skip
        if better:
            agent.best, agent.best_m = score, agent.m.copy()
            agent.best_made = {"generations": g, "probe": {
                "impulses": list(impulses), "forward": fwd, "backward": back}}
            if out is not None:
                export_linear(agent, out, agent.best_made)

    try:
        # A start from a file or from offsets given is a policy of its own: probed first, it
        # is the file kept until a generation probes as well (a --stance search from a
        # crouch that stood backward 1.4 N·s drifted to probes of 1.2 each way and kept one).
        if start is not None or stance is not None:
            probe(0)
        g = -1  # --iterations 0: the start probed and written, no generation run
        for g in range(generations):
            stats = agent.generation(pool)
            elapsed = time.monotonic() - t0
            fwd_r, back_r = stats["forward"], stats["backward"]
            print(f"generation {g + 1} shoves forward {fwd_r[0]:.1f}-{fwd_r[1]:.1f} backward "
                  f"{back_r[0]:.1f}-{back_r[1]:.1f} N·s "
                  f"score {stats['score']:.3f} stood {stats['stood']:.2f} "
                  f"|M| {float(np.abs(agent.m).sum()):.2f} elapsed {elapsed:.0f} s",
                  file=log, flush=True)  # fmt: skip
            last = minutes and elapsed > minutes * 60
            if (g + 1) % s.probe_every == 0 or last or g + 1 == generations:
                probe(g + 1)
            if last:
                break
    finally:
        if pool is not None:
            pool.close()
            pool.join()
    agent.m = agent.best_m
    if out is not None:
        export_linear(agent, out, {**agent.best_made, "trained_generations": g + 1})
    return agent


PROBE_SWEEP = (1.0, 1.2, 1.4, 1.6, 1.8, 2.0)


def _stood(impulses: Sequence[float], up: Sequence[int]) -> str:
    return " ".join(f"{i:g}{'+' if u else '-'}" for i, u in zip(impulses, up, strict=True))


def export_linear(agent: Search, out: Path, made: dict[str, Any]) -> None:
    """The reflex as an ONNX graph: Gemm (the features and their negatives), Relu, Gemm, the
    pairs' mirror map and the clip, with the deploy constants (written atomically)."""
    import onnx

    from clients.learn.onnx_policy import deploy_metadata, mlp_model
    from config.loader import load_robot
    from schemas.joints import JOINT_IDS

    robot = load_robot()
    scale = action_scale(agent.s)
    training = {"algorithm": "ARS (random search, numpy, clients/learn/train.py)", **made,
                "settings": {k: v for k, v in vars(agent.s).items()},
                "reflex": dict(zip([*agent.names, *(f"{agent.names[i]}<0" for i in agent.split)],
                                   agent.m.tolist(), strict=True))}  # fmt: skip
    meta = deploy_metadata(RATE, scale, [robot.by_id[j].p for j in JOINT_IDS],
                           **{"darwin.training": json.dumps(training)})  # fmt: skip
    w1, w2, b1 = agent.layers()
    layers = [(w1, b1), (w2, np.zeros(w2.shape[1]))]
    model = mlp_model(layers, "Relu", None, None, meta, out_map=agent.out_map)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".onnx.tmp")
    onnx.save(model, str(tmp))
    tmp.replace(out)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True, help="the .onnx file to write")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--iterations", type=int, default=10**6)
    ap.add_argument("--minutes", type=float, default=0.0, help="stop after this long (0: never)")
    ap.add_argument("--envs", type=int, default=Settings.envs)
    ap.add_argument("--horizon", type=int, default=Settings.horizon)
    ap.add_argument("--push", type=float, nargs=2, default=Settings.push, metavar=("LO", "HI"),
                    help="N·s of the shoves (forward and, without --push-back, backward)")
    ap.add_argument("--push-back", type=float, nargs=2, default=Settings.push_back,
                    metavar=("LO", "HI"), help="N·s of the backward shoves")
    ap.add_argument(
        "--imitate",
        type=int,
        default=Settings.imitate_steps,
        help="steps of stand_balance.py to copy first (0: start from holding)",
    )
    ap.add_argument("--method", choices=("ppo", "ars"), default="ppo",
                    help="ppo: the MLP, fine-tuned from the copy; ars: random search of a "
                    "linear reflex scored on the shoves stood (--iterations: generations)")
    ap.add_argument("--workers", type=int, default=1, help="ars: processes the episodes run in")
    ap.add_argument("--search", choices=("reflex", "tilt", "all"), default="reflex",
                    help="ars: which numbers are searched (docs/learning.md)")
    ap.add_argument("--randomize", choices=("playground", "latency"), default="playground",
                    help="ars: Playground's domain randomisation, or latency and IMU noise only")
    ap.add_argument("--hold", type=int, nargs=2, default=(1, 1), metavar=("LO", "HI"),
                    help="ars: steps a sensor reading may hold in the training worlds (the "
                    "loaded stack's hold 2-4)")
    ap.add_argument("--impulse-weight", type=float, default=0.0, metavar="K",
                    help="ars: an episode's score × (impulse / the middle of its direction's "
                    "range) ** K (the larger shoves of each range count more)")
    ap.add_argument("--balance", action="store_true",
                    help="ars: score a candidate by its weaker direction's shoves")
    ap.add_argument("--start", type=Path, help="ars: go on from this reflex (an .onnx it wrote)")
    ap.add_argument("--probe-hold", type=int, nargs=2, default=(1, 1), metavar=("LO", "HI"),
                    help="ars: probe on the full model with its readings held LO-HI steps, "
                    "latency and IMU noise (the loaded stack), not the nominal one")
    ap.add_argument("--tilt-zero", type=float, default=0.0, metavar="G",
                    help="ars: the gravity's x where the tilt's two sides meet (the stand "
                    "pose's lean reads 0.22)")
    ap.add_argument("--stance", type=float, nargs="*", metavar="OFFSET",
                    help="ars: search the pose the reflex rests in too, an offset per pair "
                    "(action units, added every step), starting at these (default: the "
                    "start's, or none)")
    ap.add_argument("--scale", type=float, default=0.0, metavar="RAD",
                    help="ars: rad per action unit of the worlds and the file's deploy "
                    "constants (0.01-1; default: the config's [policy] scale, 0.3)")
    ap.add_argument("--rank", choices=("weaker", "largest"), default="weaker",
                    help="ars: which probe the file keeps: most impulses stood the weaker way, "
                    "or the largest stood either way with 1.0 N·s stood both ways")
    ap.add_argument("--shove-at", type=float, default=SearchSettings.shove_at, metavar="S",
                    help="ars: s into a settled start the training episodes' shove comes (a "
                    "policy that crouches first wants the push table's 1.5)")
    args = ap.parse_args(argv)
    if args.scale and not 0.01 <= args.scale <= 1.0:
        ap.error(f"--scale {args.scale:g} is outside the daemon's 0.01-1 rad per action unit")
    given = sys.argv[1:] if argv is None else argv
    if args.method == "ars":
        print(f"training: python -m clients.learn.train {' '.join(given)}", flush=True)
        ss = SearchSettings(workers=args.workers, randomize=args.randomize, search=args.search,
                            hold=tuple(args.hold),
                            impulse_weight=args.impulse_weight,
                            balance=args.balance, tilt_zero=args.tilt_zero,
                            stance=args.stance is not None,
                            probe_hold=tuple(args.probe_hold),
                            scale=args.scale, rank=args.rank,
                            shove_at=args.shove_at)  # fmt: skip
        if args.push != Settings.push:
            ss.push = ss.push_back = tuple(args.push)
        if args.push_back:
            ss.push_back = tuple(args.push_back)
        if args.stance and len(args.stance) != len(ss.pairs):
            ap.error(f"--stance takes an offset for each of the {len(ss.pairs)} pairs "
                     f"({', '.join(ss.pairs)}), not {len(args.stance)}")
        search(ss, args.seed, args.iterations, args.minutes, args.out,
               imitate=bool(args.imitate), start=args.start,
               stance=args.stance or None)  # fmt: skip
        print(f"policy: {args.out}", flush=True)
        return 0
    s = Settings(envs=args.envs, horizon=args.horizon, push=tuple(args.push),
                 push_back=tuple(args.push_back) if args.push_back else None,
                 imitate_steps=args.imitate)  # fmt: skip
    print(f"training: python -m clients.learn.train {' '.join(given)}", flush=True)
    train(s, args.seed, args.iterations, args.minutes, args.out)
    print(f"policy: {args.out}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
