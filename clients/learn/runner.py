"""`darwin policy run FILE`: drive the robot (or the simulator) with a policy at its rate.

FILE is an ONNX model (``*.onnx``: input ``[1, 69]`` float32, the observation vector of
schemas/policy.py; output ``[1, 20]``, the action; run by onnxruntime, or by numpy over the graph
where onnxruntime is missing, as on the robot: clients/learn/onnx_policy.py), whose deploy
constants (contract version, joint order, default pose, observation layout, action scale, rate)
must match the contract and the daemon's, or a Python callable
``module:name`` / ``path.py:name`` taking the observation vector and returning the action (an
object with ``reset()`` is reset first; ``rate_hz`` on it sets the rate). The loop is the
daemon's policy stream: take the lease, bring the robot to the default pose at rest (the stand
page when it stands elsewhere: clients/learn/stream.py), start the stream, answer each
observation with one action. Any key (or Ctrl-C) is an e-stop: ``halt``, then the lease goes.
``--dry-run`` takes no lease and only publishes what it would send on ``…/policy/dry_run``.
``--sim`` runs the fast backend (on the stack's full MuJoCo model) instead of a robot (``--push
N`` shoves it every 2 s) and says how long it stood.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from clients.learn.onnx_policy import (
    META_RATE,
    META_SCALE,
    PolicyLoadError,
    contract_mismatch,
    load_onnx,
)
from schemas import qos
from schemas.errors import DarwinError
from schemas.policy import N_JOINTS, PolicyAction

__all__ = ["PolicyLoadError", "load_policy", "run", "run_sim"]

Policy = Callable[[np.ndarray], Any]


def load_policy(spec: str, engine: str = "auto") -> tuple[Policy, float | None]:
    """The policy callable of ``spec`` and its rate (Hz) when it says one. An ONNX policy's
    callable carries its metadata (``meta``) and the ``engine`` that runs it."""
    if spec.endswith(".onnx"):
        return _load_onnx(spec, engine)
    module_name, _, attr = spec.partition(":")
    if not attr:
        raise PolicyLoadError(f"{spec!r} is neither an .onnx file nor module:function")
    try:
        if module_name.endswith(".py"):
            path = Path(module_name)
            if not path.is_file():
                raise PolicyLoadError(f"{path} does not exist")
            loader = importlib.util.spec_from_file_location(path.stem, path)
            assert loader is not None and loader.loader is not None
            module = importlib.util.module_from_spec(loader)
            loader.loader.exec_module(module)
        else:
            module = importlib.import_module(module_name)
    except ImportError as exc:
        raise PolicyLoadError(f"cannot import {module_name}: {exc}") from None
    fn = getattr(module, attr, None)
    if not callable(fn):
        raise PolicyLoadError(f"{module_name} has no callable {attr!r}")
    if hasattr(fn, "reset"):
        fn.reset()
    rate = getattr(fn, "rate_hz", None)
    return fn, float(rate) if rate else None


def _load_onnx(path: str, engine: str) -> tuple[Policy, float | None]:
    run, meta, used = load_onnx(path, engine)
    why = contract_mismatch(meta)
    if why:
        raise PolicyLoadError(f"{path} is refused: {why}")
    # The loaded model carries its metadata and engine for the runner's report (a Policy is
    # typed as a plain callable).
    run.meta = meta  # type: ignore[attr-defined]
    run.engine = used  # type: ignore[attr-defined]
    return run, float(meta[META_RATE]) if META_RATE in meta else None


def _action(policy: Policy, obs: np.ndarray) -> list[float]:
    a = np.asarray(policy(obs), dtype=float).reshape(-1)
    if a.shape != (N_JOINTS,):
        raise PolicyLoadError(f"the policy returned {a.size} numbers; the action has {N_JOINTS}")
    return a.tolist()


class EStop:
    """Any key on a terminal stdin (or Ctrl-C) sets the stop."""

    def __init__(self) -> None:
        self.event = threading.Event()
        self._restore: Any = None
        if sys.stdin.isatty():
            import termios
            import tty

            fd = sys.stdin.fileno()
            old = termios.tcgetattr(fd)
            tty.setcbreak(fd)
            self._restore = lambda: termios.tcsetattr(fd, termios.TCSADRAIN, old)
            threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        with contextlib.suppress(OSError, ValueError):
            if sys.stdin.read(1):
                self.event.set()

    def close(self) -> None:
        if self._restore is not None:
            self._restore()


def run_sim(
    policy: Policy, rate: float, seconds: float, push: float, seed: int, fast: bool = False
) -> int:
    """Steps the fast backend stood (of ``seconds × rate``), pushed ``push`` N every 2 s: on
    the stack's own model (1 ms steps) unless ``fast`` (the training model) — an evaluation
    should not share the training model's approximations."""
    import gymnasium as gym

    import clients.learn.env  # noqa: F401
    from clients.learn.fast import Randomization

    steps = int(seconds * rate)
    env = gym.make("darwin/Stand-v0", rate_hz=rate, max_steps=steps, randomize=Randomization.off(),
                   fast=fast)  # fmt: skip
    meta = getattr(policy, "meta", None)
    if meta:  # at the model's action scale, as the stream on the robot starts it
        env.unwrapped.backend.scale = float(meta[META_SCALE])  # type: ignore[attr-defined]
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    period = int(2 * rate)
    for k in range(steps):
        if push and k % period == period // 2:
            stand: Any = env.unwrapped  # the DarwinStandEnv under gymnasium's wrappers
            stand.push((push * rng.choice([-1.0, 1.0]), 0.0, 0.0), 0.1)
        obs, _, terminated, _, _ = env.step(_action(policy, obs))
        if terminated:
            env.close()
            return k
    env.close()
    return steps


def run_robot(args: argparse.Namespace, policy: Policy, rate: float) -> int:
    from clients.learn.stream import PolicyStream
    from clients.robot import Robot
    from schemas.messages import encode

    robot = Robot(endpoint=args.connect, robot=args.robot, name="darwin policy run")
    print(f"robot: {robot.keys.prefix} at {robot.target.endpoint}", flush=True)
    stream = PolicyStream(robot)
    estop = EStop()
    sent = 0
    dry_key = robot.keys.policy("dry_run")
    dry_pub = (
        robot.session.declare_publisher(dry_key, **qos.for_key(dry_key).kwargs())
        if args.dry_run
        else None
    )
    try:
        meta = getattr(policy, "meta", None)
        if not args.dry_run:
            robot.acquire()
            # The policy starts where it was trained to: at rest in the default pose.
            print(f"pose: {stream.stand()}", flush=True)
            scale = float(meta[META_SCALE]) if meta else None
            stream.start(rate_hz=rate, scale=scale)
            why = contract_mismatch(meta, stream.info) if meta else ""
            if why:
                raise PolicyLoadError(f"{args.file} is refused by this daemon: {why}")
        end = time.monotonic() + args.seconds if args.seconds else float("inf")
        last = -1
        while not estop.event.is_set() and time.monotonic() < end:
            obs = stream.next_observation(last, timeout=2.0)
            if obs is None:
                raise DarwinError("no observation from the daemon for 2 s: is it running?")
            if not args.dry_run and not obs.running and sent:
                status = robot.command("policy", op="status")
                print(f"stopped by the daemon: {status.get('reason')}", flush=True)
                return 1
            last = obs.tick
            action = _action(policy, np.asarray(obs.vector(), np.float32))
            if dry_pub is not None:
                sent += 1
                dry_pub.put(encode(PolicyAction(robot.client_id, sent, action, obs.tick)))
            else:
                stream.send(action, obs.tick)
                sent += 1
        if estop.event.is_set():
            robot.halt()
            print("e-stop: halted", flush=True)
        return 0
    except KeyboardInterrupt:
        robot.halt()
        print("e-stop: halted", flush=True)
        return 130
    finally:
        estop.close()
        status = {} if args.dry_run else _quiet_status(robot)
        with contextlib.suppress(DarwinError):
            if not args.dry_run:
                stream.stop()
                robot.release()
        what = "published (dry run)" if args.dry_run else "sent"
        extra = (
            f", applied {status.get('applied')}, missed deadlines {status.get('missed_deadlines')}"
            f", lost {status.get('lost')}"
            if status
            else ""
        )
        print(f"actions: {sent} {what}{extra}", flush=True)
        stream.close()
        robot.close()


def _quiet_status(robot: Any) -> dict[str, Any]:
    try:
        return robot.command("policy", op="status")
    except DarwinError:
        return {}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True)
    run = sub.add_parser("run", help="drive the robot or the simulator with a policy")
    run.add_argument("file", help="an .onnx model or module:function / path.py:function")
    run.add_argument("--rate", type=float, help="Hz (default: the policy's, else 50)")
    run.add_argument("--seconds", type=float, default=0.0, help="stop after this long (0: never)")
    run.add_argument("--dry-run", action="store_true", help="publish on …/policy/dry_run only")
    run.add_argument("--sim", action="store_true", help="the fast MuJoCo backend, no robot")
    run.add_argument("--push", type=float, default=0.0, help="with --sim: shove N every 2 s")
    run.add_argument("--seed", type=int, default=0, help="with --sim: the episode's seed")
    run.add_argument("--connect", help="the robot's Zenoh endpoint (else DARWIN_ENDPOINT)")
    run.add_argument("--robot", help="the robot's name (else DARWIN_ROBOT)")
    run.add_argument(
        "--engine",
        choices=("auto", "onnxruntime", "numpy"),
        default="auto",
        help="what runs an .onnx policy (auto: onnxruntime where installed, else numpy)",
    )


def run(args: argparse.Namespace) -> int:
    policy, own_rate = load_policy(args.file, args.engine)
    rate = args.rate or own_rate or 50.0
    if not 25.0 <= rate <= 125.0:
        raise PolicyLoadError(f"rate {rate:g} Hz is outside 25..125 Hz")
    engine = getattr(policy, "engine", None)
    print(f"policy: {args.file} at {rate:g} Hz" + (f" ({engine})" if engine else ""), flush=True)
    if args.sim:
        seconds = args.seconds or 10.0
        stood = run_sim(policy, rate, seconds, args.push, args.seed)
        total = int(seconds * rate)
        verdict = "fell" if stood < total else "standing"
        print(f"stood: {stood / rate:.2f} s of {seconds:g} s ({verdict})")
        return 0
    return run_robot(args, policy, rate)
