"""Count, don't clock: instructions per step of the emulator's servos and of the kinematic world,
for a robot standing still (what a simulated robot does between a test's commands, and most of
what `darwin up` costs when nobody drives it).

    python benchmarks/sim_count.py                      # this tree
    python benchmarks/sim_count.py --baseline DIR       # and another tree (e.g. a `git worktree`
                                                        # of main), in the same run, with the ratio

Each figure runs itself again under ``valgrind --tool=callgrind`` and counts exactly the steps
asked for (``callgrind_requests.py`` toggles counting around them), so the figures repeat to
±0.1 % whatever the machine's load:

- ``servos``: ``Bus.step(0.004)``, every servo's motion, heat, alarms and registers (the emulator
  runs it before answering a packet and at each physics round: ~300 times a second);
- ``world``: ``SimWorld.step(0.01)``, the body's legs, balance and the ball (100 a second);
- ``answer``: the replies of the 21 devices to the daemon's bulk read of a tick (125 a second),
  and their delivery as the FTDI chip hands them over;
- ``moving``: ``Bus.step(0.004)`` while every servo moves to a goal (a driven robot: a walk, a
  page, a test's pose), and ``goals``: the sync write of 20 goals a moving robot gets each tick;
- ``plant``: a physics plant's round (the MuJoCo world's, at each step of the emulator's clock):
  ``Bus.step(0.01)``, then each servo's ``plant_update`` with its joint's state (a fixed one
  here: the engine is not counted).

The bus is brought up first as the daemon does (the servos powered, torque on, holding the pose):
an unpowered bus answers nothing, and the child refuses to count one.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve()
ROOT = HERE.parents[1]
STEPS = 100


def child(what: str, root: Path) -> None:
    sys.path[:0] = [str(root), str(HERE.parent)]
    from callgrind_requests import Callgrind

    from robot_daemon.bus.packet import instruction_packet
    from robot_daemon.bus.tables import BROADCAST_ID, CM730, MX28, Instruction, sensor_blocks
    from robot_daemon.emulator.emulator import Emulator
    from robot_daemon.emulator.settings import EmulatorSettings
    from robot_daemon.plant.world import SimWorld

    cg = Callgrind()
    emulator = Emulator(EmulatorSettings.load(realtime=False))
    world = SimWorld(seed=1)
    world.attach(emulator)

    def send(packet: bytes) -> int:
        """The packet as the daemon's port would put it on the bus; how many replies."""
        with emulator.lock:
            emulator._process(emulator.parser.feed(packet), 0.0)
            replies = len(emulator._out)
            emulator._out.clear()
        return replies

    # As the daemon brings the robot up: the servos powered, then torque on, holding the pose.
    send(instruction_packet(200, Instruction.WRITE, [CM730.DXL_POWER.reg.address, 1]))
    emulator.advance(0.5)
    torque = [MX28.TORQUE_ENABLE.reg.address, 1]
    for dxl_id in range(1, 21):
        torque += [dxl_id, 1]
    send(instruction_packet(BROADCAST_ID, Instruction.SYNC_WRITE, torque))
    emulator.advance(1.0)  # standing, settled
    positions = emulator.api.present_positions()

    param = [0x00]
    for dxl_id, start, length in sensor_blocks():
        param += [length, dxl_id, start]
    request = instruction_packet(BROADCAST_ID, Instruction.BULK_READ, param)
    answered = send(request)
    if answered == 0 or not all(emulator.api.torque_enabled().values()):
        # Counting an unpowered bus counted nothing: say so rather than print a figure.
        raise SystemExit(f"sim_count: the bus is not up (bulk read: {answered} deliveries)")

    def answer() -> None:
        send(request)

    # Goals 300 units off at a slow moving speed: each servo still moves after the counted steps.
    goals = [MX28.GOAL_POSITION.reg.address, 4]
    for dxl_id in range(1, 21):
        goal = 2048 + (300 if dxl_id % 2 else -300)
        goals += [dxl_id, goal & 0xFF, goal >> 8, 10, 0]
    goal_write = instruction_packet(BROADCAST_ID, Instruction.SYNC_WRITE, goals)
    if what == "moving":
        send(goal_write)

    def plant() -> None:
        emulator.bus.step(0.01)
        for servo in emulator.bus.servos.values():
            servo.plant_update(2048.5, 10.0, 0.5, False, 0.01)

    step = {
        "servos": lambda: emulator.bus.step(0.004),
        "world": lambda: world.step(0.01, positions),
        "answer": answer,
        "moving": lambda: emulator.bus.step(0.004),
        "goals": lambda: send(goal_write),
        "plant": plant,
    }[what]
    cg.start_instrumentation()
    for _ in range(20):
        step()
    cg.zero()
    cg.toggle()
    for _ in range(STEPS):
        step()
    cg.toggle()


def count(what: str, root: Path) -> float:
    """Thousands of instructions per step of ``what`` in the tree at ``root``."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "callgrind.out"
        cmd = [
            "valgrind", "--tool=callgrind", "--collect-atstart=no", "--instr-atstart=no",
            f"--callgrind-out-file={out}", f"--log-file={out}.log",
            sys.executable, str(HERE), "--child", what, "--root", str(root),
        ]  # fmt: skip
        env = dict(os.environ, PYTHONHASHSEED="0", PYTHONDONTWRITEBYTECODE="1")
        done = subprocess.run(cmd, env=env, cwd=root, capture_output=True, text=True)
        if done.returncode != 0:
            raise SystemExit(f"sim_count: the counted child failed: {done.stderr[-500:]}")
        found = re.search(r"^(?:summary|totals):\s+(\d+)", out.read_text(), re.M)
        if found is None:
            raise SystemExit(f"sim_count: no totals in {out}")
        return int(found.group(1)) / STEPS / 1000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", type=Path, help="another source tree, counted in this run")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--root", type=Path, default=ROOT, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.root)
        return
    if shutil.which("valgrind") is None:
        raise SystemExit("sim_count: valgrind is not installed: apt-get install valgrind")
    for what in ("servos", "world", "answer", "moving", "goals", "plant"):
        now = count(what, ROOT)
        line = f"{what}: {now:,.0f} k instructions a step"
        if args.baseline is not None:
            before = count(what, args.baseline.resolve())
            line += f" (baseline {before:,.0f} k: ×{now / before:.2f})"
        print(line, flush=True)


if __name__ == "__main__":
    main()
