"""Robot learning figures: the fast backend, the stack, the policy loop, the per-tick cost.

    .venv/bin/python benchmarks/learn_benchmark.py [--steps 500] [--seconds 10]

1. Fast backend (clients/learn/fast.py): env steps/s and real-time factor at 50 Hz, against
   the bare plant (``mj_step`` on the same model, same number of physics steps) in this run.
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
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import gymnasium as gym

import clients.learn.env  # noqa: F401
from clients.learn.fast import Randomization

RATE = 50.0


def fast_backend(steps: int) -> None:
    env = gym.make("darwin/Stand-v0", randomize=Randomization.off(), max_steps=10**9)
    env.reset(seed=0)
    backend = env.unwrapped.backend
    t = time.perf_counter()
    for _ in range(steps):
        env.step(np.zeros(20))
    wall = time.perf_counter() - t
    plant = backend.plant
    n_phys = int(steps / RATE / plant.model.opt.timestep)
    t = time.perf_counter()
    plant.mj.mj_step(plant.model, plant.data, nstep=n_phys)
    bare = time.perf_counter() - t
    print(f"fast backend: {steps / wall:.0f} steps/s, real-time factor {steps / RATE / wall:.1f}")
    print(f"bare mj_step of the same {n_phys} physics steps: real-time factor "
          f"{steps / RATE / bare:.1f}; env overhead ×{wall / bare:.2f}")  # fmt: skip
    env.close()


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
              f"{status['refused'] or 0}")  # fmt: skip
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
    args = ap.parse_args()
    tick_cost()
    fast_backend(args.steps)
    if not args.skip_stack:
        stack(min(args.steps, 250))
        policy_loop(args.seconds)


if __name__ == "__main__":
    main()
