"""Emulator figures: bulk-read round trip against the 1 Mbps wire floor, and idle CPU.

    .venv/bin/python benchmarks/sim_bus.py [--rounds 300]

Prints, for the daemon's per-tick bulk read (20 servos × 6 bytes + the CM-730's 30 bytes, one
transaction through the daemon's bus code, ``DxlBus.bulk_read`` on dynamixel-sdk): median / p99
round trip over the pty without wire timing (the emulator's own cost) and with it, for an
in-process Emulator (which shares the GIL with the client) and for ``darwin sim`` in its own
process, and over the in-process link the simulated rig uses (no pty, a simulated wire: the
protocol code's own cost), against the wire floor the bytes need at 1 Mbps. Then the CPU the
emulator uses while the bus is idle, and while a client bulk-reads every 8 ms.
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

from robot_daemon.bus.dxl import DxlBus, ReplyBudget
from robot_daemon.bus.port import BlockingPortHandler
from robot_daemon.bus.tables import CM730, CM730_ID, SERVO_IDS, sensor_blocks
from robot_daemon.bus.transport import Transport
from robot_daemon.emulator import Emulator, EmulatorSettings
from robot_daemon.emulator.inprocess_link import EmulatorLink
from schemas import units
from tests.fixtures.emulator import darwin_command, start_emulator_process


def round_trips(wire_timing: bool, rounds: int) -> list[float]:
    settings = EmulatorSettings(seed=1, wire_timing=wire_timing, power_on_delay_s=0.0)
    with Emulator(settings) as emu:
        return timed_bulk_reads(BlockingPortHandler(emu.port), rounds)


def link_round_trips(rounds: int) -> list[float]:
    """Over the in-process link (what ``SimRig`` runs): the protocol code and the emulator's
    packet handling, no pty and no waiting."""
    emu = Emulator(EmulatorSettings(seed=1, realtime=False, power_on_delay_s=0.0))
    return timed_bulk_reads(EmulatorLink(emu), rounds)


def timed_bulk_reads(transport: Transport, rounds: int) -> list[float]:
    """Round trips (s) of the daemon's per-tick bulk read through its own bus code."""
    transport.open(1_000_000)
    try:
        # A generous margin: a late reply should be timed, not given up on.
        bus = DxlBus(transport, ReplyBudget(margin_ms=30.0))
        bus.write(CM730_ID, CM730.DXL_POWER.reg.address, b"\x01", tries=3)
        blocks = sensor_blocks()
        times = []
        incomplete = 0
        for _ in range(rounds):
            start = time.perf_counter()
            incomplete += bool(bus.bulk_read(blocks).missing)
            times.append(time.perf_counter() - start)
        if incomplete:
            print(f"  ({incomplete} of {rounds} bulk reads missed a reply: a busy machine)")
        return times
    finally:
        transport.close()


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
        return timed_bulk_reads(BlockingPortHandler(sim.port), rounds)


def cpu_share(seconds: float, tick: float | None) -> float:
    """Process CPU per wall second with an emulator running (and a client every ``tick``)."""
    with Emulator(EmulatorSettings(seed=1, power_on_delay_s=0.0)) as emu:
        port = BlockingPortHandler(emu.port)
        port.open(1_000_000)
        bus = DxlBus(port, ReplyBudget(margin_ms=30.0))
        bus.write(CM730_ID, CM730.DXL_POWER.reg.address, b"\x01", tries=3)
        blocks = sensor_blocks()
        cpu0, wall0 = time.process_time(), time.monotonic()
        next_tick = wall0
        while time.monotonic() - wall0 < seconds:
            if tick is None:
                time.sleep(seconds)
                break
            bus.bulk_read(blocks)
            next_tick += tick
            time.sleep(max(0.0, next_tick - time.monotonic()))
        share = (time.process_time() - cpu0) / (time.monotonic() - wall0)
        port.close()
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
    describe("in-process link", link_round_trips(args.rounds), floor)
    idle = cpu_share(2.0, None)
    busy = cpu_share(2.0, 0.008)
    print(f"CPU, idle emulator      {idle * 100:5.1f} % of a core")
    print(f"CPU, bulk read / 8 ms   {busy * 100:5.1f} % of a core (client + emulator, one process)")


if __name__ == "__main__":
    main()
