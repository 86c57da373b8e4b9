"""Emulator figures: bulk-read round trip against the 1 Mbps wire floor, and idle CPU.

    .venv/bin/python benchmarks/sim_bus.py [--rounds 300]

Prints, for the daemon's per-tick bulk read (20 servos × 6 bytes + the CM-730's 30 bytes, one
transaction through dynamixel-sdk over the pty): median / p99 round trip without wire timing (the
emulator's own cost) and with it, for an in-process Emulator (which shares the GIL with the
client) and for ``darwin sim`` in its own process, against the wire floor the bytes need at
1 Mbps. Then the CPU the emulator uses while the bus is idle, and while a client
bulk-reads every 8 ms.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dynamixel_sdk import COMM_SUCCESS

from robot_daemon.bus.tables import CM730_ID, SERVO_IDS
from robot_daemon.sim import Emulator, EmulatorSettings
from schemas import units
from tests.fixtures.emulator import darwin_command, open_sdk, start_emulator_process
from tests.integration.test_sim_sdk import sensor_bulk_read


def round_trips(wire_timing: bool, rounds: int) -> list[float]:
    settings = EmulatorSettings(seed=1, wire_timing=wire_timing, power_on_delay_s=0.0)
    with Emulator(settings) as emu:
        return timed_bulk_reads(emu.port, rounds)


def timed_bulk_reads(port_name: str, rounds: int) -> list[float]:
    """Round trips (s) of the daemon's per-tick bulk read, through the SDK on ``port_name``."""
    port, ph = open_sdk(port_name)
    try:
        reader = sensor_bulk_read(port, ph)
        times = []
        for _ in range(rounds):
            start = time.perf_counter()
            if reader.txRxPacket() != COMM_SUCCESS:
                raise RuntimeError("bulk read failed")
            times.append(time.perf_counter() - start)
        return times
    finally:
        port.closePort()


def process_round_trips(wire_timing: bool, rounds: int) -> list[float]:
    """The same against ``darwin sim`` in its own process (no GIL shared with the client)."""
    help_text = subprocess.run(
        darwin_command("sim", "--help"), capture_output=True, text=True, check=True
    ).stdout
    args = ["--power-on-delay", "0", *([] if wire_timing else ["--no-wire-timing"])]
    if "--no-world" in help_text:  # the bus alone: the world's physics is not measured here
        args.append("--no-world")
    with (
        tempfile.TemporaryDirectory() as tmp,
        start_emulator_process(*args, link_dir=Path(tmp), control=False) as sim,
    ):
        return timed_bulk_reads(sim.port, rounds)


def cpu_share(seconds: float, tick: float | None) -> float:
    """Process CPU per wall second with an emulator running (and a client every ``tick``)."""
    with Emulator(EmulatorSettings(seed=1, power_on_delay_s=0.0)) as emu:
        port, ph = open_sdk(emu.port)
        reader = sensor_bulk_read(port, ph)
        cpu0, wall0 = time.process_time(), time.monotonic()
        next_tick = wall0
        while time.monotonic() - wall0 < seconds:
            if tick is None:
                time.sleep(seconds)
                break
            reader.txRxPacket()
            next_tick += tick
            time.sleep(max(0.0, next_tick - time.monotonic()))
        share = (time.process_time() - cpu0) / (time.monotonic() - wall0)
        port.closePort()
    return share


def describe(name: str, times: list[float], floor: float) -> None:
    med = statistics.median(times)
    p99 = sorted(times)[int(0.99 * (len(times) - 1))]
    print(
        f"{name:<22} median {med * 1e3:6.2f} ms  p99 {p99 * 1e3:6.2f} ms  ×floor {med / floor:5.2f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=300)
    args = parser.parse_args()
    n_devices = len(SERVO_IDS) + 1
    wire_bytes = (7 + 3 * n_devices) + len(SERVO_IDS) * (6 + 6) + (6 + 30)
    floor = units.wire_time_s(wire_bytes)
    print(f"bulk read of {len(SERVO_IDS)} servos + CM-730 (ID {CM730_ID}): {wire_bytes} bytes")
    print(f"{'wire floor (1 Mbps)':<22} {floor * 1e3:6.2f} ms")
    describe("in-process, no wire", round_trips(False, args.rounds), floor)
    describe("in-process, wire", round_trips(True, args.rounds), floor)
    describe("process, no wire", process_round_trips(False, args.rounds), floor)
    describe("process, wire", process_round_trips(True, args.rounds), floor)
    idle = cpu_share(2.0, None)
    busy = cpu_share(2.0, 0.008)
    print(f"CPU, idle emulator      {idle * 100:5.1f} % of a core")
    print(f"CPU, bulk read / 8 ms   {busy * 100:5.1f} % of a core (client + emulator, one process)")


if __name__ == "__main__":
    main()
