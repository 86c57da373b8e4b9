"""Robot learning figures: the fast backend, the stack, the policy loop, the per-tick cost.

    .venv/bin/python benchmarks/learn_benchmark.py [--steps 500] [--seconds 10] [--fast-only]

1. Fast backend (clients/learn/fast.py): env steps/s at 50 Hz (wall, and per second of this
   process's CPU: the one-core figure on a shared machine) for the training model
   (``[physics.fast]``) and the full one, each against bare ``mj_step`` of the same model over
   the same simulated time, in this run; then the vectorised env (``gym.make_vec``): ``--worlds``
   worlds in one process (sync) and one process per core (async).
2. Stack backend: the real-time factor of ``darwin up --physics mujoco`` driven by the env.
3. The policy loop with a client streaming at 50 Hz over Zenoh (``darwin up``): observation →
   applied latency p50/p99 (the daemon's PolicyApplied.latency), missed deadlines, overruns,
   refusals; baseline: the round trip of a command query (``policy`` op=status) measured the
   same way, the cost a query per action would add.
4. Per-tick CPU cost of the policy module in the motion loop (gravity filter + observation
   every 2.5 ticks), idle and streaming, in process CPU time per tick, against the motion
   manager's tick without it.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import gymnasium as gym

import clients.learn.env  # noqa: F401
from clients.learn.fast import Randomization

RATE = 50.0


def _steps_per_s(env: gym.Env, steps: int) -> tuple[float, float]:
    """Env steps per second of wall time and of this process's CPU time."""
    zero = np.zeros(20)
    t, c = time.perf_counter(), time.process_time()
    for _ in range(steps):
        env.step(zero)
    return steps / (time.perf_counter() - t), steps / (time.process_time() - c)


def _bare(plant, seconds: float) -> tuple[int, float, float]:  # type: ignore[no-untyped-def]
    """``mj_step`` alone over ``seconds`` of simulated time: physics steps, wall, CPU."""
    n = int(round(seconds / plant.model.opt.timestep))
    t, c = time.perf_counter(), time.process_time()
    plant.mj.mj_step(plant.model, plant.data, nstep=n)
    return n, time.perf_counter() - t, time.process_time() - c


def fast_backend(steps: int, worlds: int) -> None:
    """The training model (``[physics.fast]``) and the full one (the stack's), each beside bare
    ``mj_step`` of the same model; then the vectorised env (Gymnasium's vector API)."""
    for fast in (False, True):
        env = gym.make("darwin/Stand-v0", randomize=Randomization.off(), max_steps=10**9,
                       fast=fast)  # fmt: skip
        env.reset(seed=0)
        plant = env.unwrapped.backend.plant
        wall, cpu = _steps_per_s(env, steps)
        n, _, bare_cpu = _bare(plant, steps / RATE)
        name = "fast model" if fast else "full model"
        ts = plant.model.opt.timestep * 1000
        bare = steps / bare_cpu
        print(f"{name} ({ts:g} ms steps): env {wall:.0f} steps/s wall, {cpu:.0f} steps/s CPU "
              f"({cpu / RATE:.0f}× real time on one core); bare mj_step of the same model: "
              f"{bare:.0f} policy steps/s CPU ({n} physics steps in {bare_cpu:.2f} s, "
              f"{bare / RATE:.0f}× real time); env / bare ×{bare / cpu:.2f}")  # fmt: skip
        env.close()
    for mode, n_envs in (("sync", worlds), ("async", os.cpu_count() or 1)):
        envs = gym.make_vec("darwin/Stand-v0", num_envs=n_envs, vectorization_mode=mode,
                            randomize=Randomization.off(), max_steps=10**9)  # fmt: skip
        envs.reset(seed=0)
        zero = np.zeros((n_envs, 20))
        rounds = max(1, steps // n_envs)
        t, c = time.perf_counter(), time.process_time()
        for _ in range(rounds):
            envs.step(zero)
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        where = "worlds in this process" if mode == "sync" else "processes, one per core"
        cpu_note = f", {rounds * n_envs / cpu:.0f} steps/s of this process's CPU"
        print(f"vectorised ({mode}, {n_envs} {where}): {rounds * n_envs / wall:.0f} steps/s "
              f"wall{cpu_note if mode == 'sync' else ''}")  # fmt: skip
        envs.close()


def stack(steps: int) -> None:
    from tests.fixtures.system import start_system

    up = start_system(gateway=False, extra_args=["--physics", "mujoco"])
    with up as system, system.robot_client(name="bench") as robot:
        robot.wait_for("joints", timeout=30)
        env = gym.make("darwin/Stand-v0", backend="stack", robot=robot, max_steps=10**9)
        env.reset(seed=0)
        t = time.perf_counter()
        t0 = env.unwrapped.backend.time
        for _ in range(steps):
            env.step(np.zeros(20))
        wall = time.perf_counter() - t
        sim = env.unwrapped.backend.time - t0
        print(f"stack backend: {steps / wall:.1f} steps/s, real-time factor {sim / wall:.2f}")
        env.close()


def policy_loop(seconds: float) -> None:
    from clients.learn.stream import PolicyStream
    from tests.fixtures.system import start_system

    with start_system(gateway=False) as system, system.robot_client(name="bench") as robot:
        robot.wait_for("joints", timeout=30)
        robot.acquire()
        rtt = []
        for _ in range(50):
            t = time.perf_counter()
            robot.command("policy", op="status")
            rtt.append(time.perf_counter() - t)
        stream = PolicyStream(robot).start(rate_hz=RATE)
        last = -1
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            obs = stream.next_observation(last)
            assert obs is not None
            last = obs.tick
            stream.send(np.zeros(20).tolist(), obs.tick)
        time.sleep(0.1)
        status = robot.command("policy", op="status")
        stream.stop()
        stream.close()
        lat = np.array([a.latency for a in stream.applied if not a.refused and a.latency > 0])
        q50, q99 = np.percentile(np.array(rtt) * 1000, [50, 99])
        print(f"policy loop at {RATE:g} Hz for {seconds:g} s: {status['applied']} applied, "
              f"latency obs→applied p50 {np.percentile(lat, 50) * 1000:.1f} ms "
              f"p99 {np.percentile(lat, 99) * 1000:.1f} ms, missed deadlines "
              f"{status['missed_deadlines']}, overruns {status['overruns']}, refused "
              f"{status['refused'] or 0}, lost {status['lost']}")  # fmt: skip
        print(f"baseline: command query round trip p50 {q50:.1f} ms p99 {q99:.1f} ms "
              f"(a query per action would add this to every action)")  # fmt: skip


def tick_cost(ticks: int = 20000) -> None:
    from config.loader import load_all, load_robot
    from robot_daemon.frames import JointFrame
    from robot_daemon.motion.setup import build_manager
    from schemas.policy import PolicyAction

    robot, settings = load_robot(), load_all()

    offer_s = [0.0]

    def run(with_policy: bool, streaming: bool) -> float:
        manager = build_manager(robot, settings)
        policy = manager.get("policy")
        if not with_policy:
            manager.modules.remove(policy)
        else:
            policy.sink = lambda topic, msg: None
        frame = JointFrame(0, 0.0, 0.008)
        frame.online[:] = True
        key = b""
        if streaming:
            manager.step(frame)
            policy.clock = lambda: frame.time
            key = policy.start("bench", RATE, "offset", 0.3)
        t = time.process_time()
        for k in range(1, ticks):
            frame.tick, frame.time = k, k * 0.008
            if streaming and k % 2 == 0:  # ~50 Hz at 8 ms ticks (every 2nd; the worst case)
                action = PolicyAction.signed("bench", key, k, [0.0] * 20, k - 1)
                t_offer = time.process_time()
                policy.offer(action)  # in the daemon: Zenoh's thread, not the loop's
                offer_s[0] += time.process_time() - t_offer
            manager.step(frame)
        return (time.process_time() - t - offer_s[0]) / ticks * 1e6

    base = run(False, False)
    idle = run(True, False)
    busy = run(True, True)
    print(f"motion manager tick (process CPU): without the policy module {base:.1f} µs, "
          f"with it idle {idle:.1f} µs (+{idle - base:.1f}), streaming {busy:.1f} µs "
          f"(+{busy - base:.1f}); checking an action (subscriber thread) "
          f"{offer_s[0] / (ticks // 2) * 1e6:.1f} µs")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--skip-stack", action="store_true", help="no `darwin up` parts")
    ap.add_argument("--fast-only", action="store_true", help="only the fast backend's figures")
    ap.add_argument("--worlds", type=int, default=8, help="worlds in one process (sync vector)")
    args = ap.parse_args()
    if args.fast_only:
        fast_backend(args.steps, args.worlds)
        return
    tick_cost()
    fast_backend(args.steps, args.worlds)
    if not args.skip_stack:
        stack(min(args.steps, 250))
        policy_loop(args.seconds)


if __name__ == "__main__":
    main()
