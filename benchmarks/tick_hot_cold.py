"""The motion tick's own Python, run back to back and run at the loop's pace: what this machine
adds to code that runs once every 8 ms.

    python benchmarks/tick_hot_cold.py [--ticks 2000] [--tick-ms 8]

One thread runs the daemon's tick (``RobotBus.read_sensors`` and ``frame``, the motion
manager's ``step`` with the robot walking, ``RobotBus.write_targets``, and the joints and IMU
messages built and encoded) over a transport that answers at once with replies recorded from
the emulator, so only the daemon's Python is measured: no emulator, no waiting, no Zenoh. It
runs the same ticks twice: **hot**, one after another, and **paced**, each after a sleep to the
next deadline as the loop does. Thread CPU time (user + system) per phase, in µs a tick.

On a dedicated computer the two are close. On a virtual machine whose core runs other tenants
while this one sleeps, the paced tick finds its caches and TLB cold and costs several times
the hot one: that factor is the machine's, and multiplies every figure of
``loop_benchmark.py`` and ``loop_phases.py``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from robot_daemon.bus.tables import Instruction
from robot_daemon.bus.transport import Transport
from robot_daemon.engine.broadcast import JointsEncoder, imu_payload
from robot_daemon.engine.snapshot import take
from robot_daemon.motion.fall import FallMonitor
from tests.fixtures.sim_rig import SimRig

PHASES = ("read_sensors", "frame", "step", "write_targets", "messages")


class Replay(Transport):
    """Records what the emulator's link answers to each BULK_READ, then answers from that at
    once (writes without a reply are taken and dropped)."""

    def __init__(self, inner: Transport) -> None:
        super().__init__("replay")
        self.inner = inner
        self.set_baud(1_000_000)
        self.recording = True
        self.replies: dict[bytes, bytearray] = {}
        self._key: bytes | None = None
        self._rx = b""

    def open(self, baudrate: int) -> None:
        self.set_baud(baudrate)

    def close(self) -> None:
        pass

    def clearPort(self) -> None:
        if self.recording:
            self.inner.clearPort()

    def getCurrentTime(self) -> float:
        return self.inner.getCurrentTime() if self.recording else time.perf_counter() * 1e3

    def idle_until(self, clock_ms: float) -> None:
        if self.recording:
            self.inner.idle_until(clock_ms)

    def writePort(self, packet: list[int] | bytes) -> int:
        data = bytes(packet)
        bulk = len(data) > 4 and data[4] == Instruction.BULK_READ
        if self.recording:
            self._key = data if bulk else None
            if bulk:
                self.replies[data] = bytearray()
            return self.inner.writePort(data)
        self._rx = bytes(self.replies.get(data, b"")) if bulk else b""
        return len(data)

    def read_chunk(self, deadline: float) -> bytes:
        if self.recording:
            chunk = self.inner.read_chunk(deadline)
            if self._key is not None:
                self.replies[self._key] += chunk
            return chunk
        chunk, self._rx = self._rx, b""
        return chunk


def walking_rig(walking: bool = True, seconds: float = 3.0) -> tuple[SimRig, Replay]:
    rig = SimRig(seed=1)
    replay = Replay(rig.link)
    rig.bus.dxl.port = replay  # type: ignore[union-attr]
    rig.bus.handler = replay  # type: ignore[assignment]
    if not rig.calibrated():
        raise SystemExit("tick_hot_cold: the simulated gyro never calibrated")
    if walking:
        rig.manager.module("walking").start(0.05, 0.0, 0.0)
    rig.run(seconds)  # every slow-read and probe variant of the bulk read recorded, the walk going
    replay.recording = False
    return rig, replay


def run(rig: SimRig, ticks: int, tick_s: float, paced: bool) -> dict[str, float]:
    bus, manager = rig.bus, rig.manager
    fall = manager.get("fall")
    fall = fall if isinstance(fall, FallMonitor) else None
    acc = dict.fromkeys(PHASES, 0.0)
    clock = time.thread_time
    deadline = time.monotonic()
    joints = JointsEncoder(rig.robot)
    for _ in range(ticks):
        if paced:
            deadline += tick_s
            time.sleep(max(0.0, deadline - time.monotonic()))
        t0 = clock()
        bus.read_sensors()
        t1 = clock()
        frame = bus.frame(rig.tick, rig.time, tick_s)
        t2 = clock()
        targets = manager.step(frame)
        t3 = clock()
        bus.write_targets(targets)
        t4 = clock()
        snap = take(bus, frame, rig.time, rig.tick, fall.direction if fall else "none")
        joints.encode(snap)
        imu_payload(snap)
        t5 = clock()
        rig.tick += 1
        rig.time += tick_s
        for name, a, b in zip(PHASES, (t0, t1, t2, t3, t4), (t1, t2, t3, t4, t5), strict=True):
            acc[name] += b - a
    return {k: v / ticks * 1e6 for k, v in acc.items()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--ticks", type=int, default=2000)
    parser.add_argument("--tick-ms", type=float, default=8.0)
    args = parser.parse_args()
    rig, _ = walking_rig()
    tick_s = args.tick_ms / 1000
    run(rig, 300, tick_s, paced=False)  # warm
    hot = run(rig, args.ticks, tick_s, paced=False)
    paced = run(rig, args.ticks, tick_s, paced=True)
    walking = rig.manager.module("walking")
    print(f"walking: {walking.running}; {args.ticks} ticks each; µs of thread CPU a tick")
    print(f"{'phase':15}{'hot':>8}{'paced':>8}{'ratio':>8}")
    for name in PHASES:
        print(f"{name:15}{hot[name]:8.1f}{paced[name]:8.1f}{paced[name] / hot[name]:8.2f}")
    h, p = sum(hot.values()), sum(paced.values())
    print(f"{'whole tick':15}{h:8.1f}{p:8.1f}{p / h:8.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
