"""Shoves of rising impulse on the whole stack: which policy stays up.

    .venv/bin/python benchmarks/push_table.py [--tries 4] [--impulses 1.0 1.2 1.4 1.6]

``darwin up --physics mujoco`` (daemon + emulator + the full MuJoCo plant, in real time; with
``[policy] damp_after = 1.0`` and ``silence_timeout = 3.0``: on a loaded machine a late action
must not soften the joints, the table is of the policies, not of the scheduler); for
each policy, impulse and try: the stand page, the robot placed standing, the lease released;
then ``darwin policy run POLICY --seconds 5`` in its own process, and 1.5 s after its stream
runs one shove of the impulse (N·s, over 0.1 s at the torso) forward or backward: half the
tries each way (the robot falls forward more easily than backward), in a seeded order, the
same for every policy. A fall is the daemon's own termination of the stream ("stopped by the
daemon: fall…"). The policies: the trained one (clients/learn/policies/stand_push.onnx, or
``--trained FILE [FILE…]``: several trained files are rows of their own, named by their
file names, so a new policy meets the shipped one under the same shoves in the same run), the
hand-made ankle controller (clients/learn/examples/stand_balance.py) and holding the stand
pose. Prints the table: impulse → falls out of N, per policy. A try whose policy stream is not
seen running (a start slower than ``START_WAIT`` under load, a stand page halted, a lease
that came late, a run the status poll missed whole) gets no shove: it is tried again, up to
``STARTS`` times, each said in a line, and then left out of its cell (which then counts
fewer tries).
"""

from __future__ import annotations

import argparse
import contextlib
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from schemas.errors import DarwinError  # noqa: E402
from schemas.sim_control import SimControl  # noqa: E402
from tests.fixtures.system import start_system  # noqa: E402

POLICIES = {
    "trained": str(ROOT / "clients/learn/policies/stand_push.onnx"),
    "stand_balance": "clients.learn.examples.stand_balance:policy",
    "hold": "clients.learn.examples.stand_balance:hold",
}
PUSH_S = 0.1
SETTLE_S = 1.5
RUN_S = 5.0
WAIT = 15.0
# s a try waits to see its policy stream running: `darwin policy run` imports, checks the pose
# and waits for the robot to be at rest first, which on a loaded machine took over 15 s.
START_WAIT = 30.0


def prepare(robot, sim: SimControl) -> None:  # type: ignore[no-untyped-def]
    """Standing at rest in the stand page's pose, nobody holding the lease. Tried again from
    the start when it fails: on a loaded machine a renewal can come late, the lease then ends
    with a safe stop and the stand page is cut short (a run of this table lost a lease in 80
    tries and the robot never came upright)."""
    for attempt in range(3):
        try:
            _prepare(robot, sim)
            return
        except (TimeoutError, DarwinError) as exc:
            print(f"prepare: {exc}; again ({attempt + 1} of 3)", flush=True)
            with contextlib.suppress(TimeoutError, DarwinError):
                robot.release()
    raise RuntimeError("three preparations did not leave the robot standing")


def _prepare(robot, sim: SimControl) -> None:  # type: ignore[no-untyped-def]
    robot.acquire()
    robot.command("halt")
    sim.call("place_robot", x=-1.0, y=0.0, yaw=0.0)
    robot.action("stand")
    # The page's start may come before or after the next status: wait for it to play, then end.
    with contextlib.suppress(TimeoutError, DarwinError):
        robot.wait_for("status", lambda s: s.motion["action"]["playing"], 2.0)
    robot.wait_for("status", lambda s: not s.motion["action"]["playing"], WAIT)
    sim.call("place_robot", x=-1.0, y=0.0, yaw=0.0)
    time.sleep(1.0)  # a benchmark: let it settle in the pose
    robot.wait_for("status", lambda s: s.motion["fall"]["state"] == "upright", WAIT)
    robot.release()


class NotStarted(Exception):
    """The policy's stream was not seen running before the shove was due (a start slower
    than ``START_WAIT`` under load, or a run the status poll missed whole): no shove was given."""


STARTS = 3  # tries of a cell's try whose stream did not start before it is left out


def one_try(system, robot, sim: SimControl, spec: str, force: float) -> bool | None:  # type: ignore[no-untyped-def]
    """Whether the robot fell (the daemon ended the policy's stream for a fall after the
    shove); a start that found it fallen already is tried again, and so is one whose stream
    did not start (up to ``STARTS`` times, each said in a line). None: the try was never
    shoved (left out of its cell, and the cell says so)."""
    fallen = not_started = 0
    while True:
        try:
            fell = _try(system, robot, sim, spec, force)
        except NotStarted as exc:
            not_started += 1
            again = "trying again" if not_started < STARTS else "left out of the table"
            print(f"  the policy stream did not start ({exc}); {again} "
                  f"({not_started} of {STARTS})", flush=True)  # fmt: skip
            if not_started == STARTS:
                return None
            continue
        if fell is not None:
            return fell
        fallen += 1
        if fallen == 3:
            raise RuntimeError("three starts found the robot fallen before the shove")


def _try(system, robot, sim: SimControl, spec: str, force: float) -> bool | None:  # type: ignore[no-untyped-def]
    prepare(robot, sim)
    proc = subprocess.Popen(
        [sys.executable, "-m", "robot_daemon.launch.cli", "policy", "run", spec,
         "--seconds", str(RUN_S), "--connect", system.endpoint, "--robot", system.robot],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, stdin=subprocess.DEVNULL,
        cwd=ROOT,
    )  # fmt: skip
    # Polled: a benchmark, and the status reply is the daemon's own view of the stream.
    end = time.monotonic() + START_WAIT
    while robot.command("policy", op="status").get("state") != "running":
        late = time.monotonic() > end
        if proc.poll() is not None or late:
            if late:  # still starting: it must not take the lease in the next try
                proc.kill()
            out = proc.communicate()[0]
            if "stopped by the daemon: fall" in out:
                return None  # fallen before the shove: not a try
            last = out.strip().splitlines()[-1] if out.strip() else "no output"
            raise NotStarted(f"after {START_WAIT:g} s" if late else f"the run ended: {last[-200:]}")
        time.sleep(0.05)
    time.sleep(SETTLE_S)
    sim.call("push", fx=force, fy=0.0, fz=0.0, duration=PUSH_S)
    out = proc.communicate(timeout=RUN_S + WAIT)[0]
    return "stopped by the daemon: fall" in out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tries", type=int, default=4)
    ap.add_argument("--impulses", type=float, nargs="+", default=[1.0, 1.2, 1.4, 1.6])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--trained", nargs="+", default=[POLICIES["trained"]],
                    help="the trained policy's file (several: a row each, named by file name)")
    ap.add_argument("--policies", nargs="+", choices=list(POLICIES), default=list(POLICIES),
                    help="which rows to run (the shoves' directions are the same for any)")
    args = ap.parse_args()
    rows = {}
    if "trained" in args.policies:
        for file in args.trained:
            rows["trained" if len(args.trained) == 1 else Path(file).name] = file
    rows.update({n: POLICIES[n] for n in ("stand_balance", "hold") if n in args.policies})
    POLICIES.clear()
    POLICIES.update(rows)
    rng = np.random.default_rng(args.seed)
    both = [1.0, -1.0] * ((args.tries + 1) // 2)
    signs = [rng.permutation(both)[: args.tries] for _ in args.impulses]
    falls: dict[str, list[int]] = {name: [] for name in POLICIES}
    shoved: dict[str, list[int]] = {name: [] for name in POLICIES}  # tries not left out
    config = Path(tempfile.mkdtemp()) / "patient.toml"
    config.write_text("[policy]\ndamp_after = 1.0\nsilence_timeout = 3.0\n")
    with (
        start_system(gateway=False, extra_args=["--physics", "mujoco", "--config", str(config)])
        as system,
        system.robot_client(name="push table") as robot,
    ):
        robot.wait_for("joints", timeout=30)
        sim = SimControl(robot.session, robot.target.robot)
        for i, impulse in enumerate(args.impulses):
            for name, spec in POLICIES.items():
                tried = [one_try(system, robot, sim, spec, s * impulse / PUSH_S) for s in signs[i]]
                pairs = [(f, s) for f, s in zip(tried, signs[i], strict=True) if f is not None]
                fell = [f for f, _ in pairs]
                falls[name].append(sum(fell))
                shoved[name].append(len(fell))
                ways = {"forward": [f for f, s in pairs if s > 0],
                        "backward": [f for f, s in pairs if s < 0]}  # fmt: skip
                left = len(tried) - len(fell)
                print(f"{impulse:.1f} N·s {name}: {sum(fell)}/{len(fell)} fell ("
                      + ", ".join(f"{w} {sum(f)}/{len(f)}" for w, f in ways.items())
                      + (f"; {left} left out, its stream did not start" if left else "") + ")",
                      flush=True)  # fmt: skip
    names = list(POLICIES)
    print(f"\nfalls out of {args.tries} per shove (whole stack, `darwin policy run`; a cell of "
          f"fewer: tries left out after their stream did not start {STARTS} times):")
    print("| impulse (N·s) | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(names))
    for i, impulse in enumerate(args.impulses):
        cells = " | ".join(f"{falls[n][i]}/{shoved[n][i]}" for n in names)
        print(f"| {impulse:.1f} | {cells} |")


if __name__ == "__main__":
    main()
