"""Count, don't clock: instructions and Atom-geometry cache misses of the motion tick under
callgrind, and the time they model on the robot's Atom Z530.

    python benchmarks/tick_count.py tick [--ticks 40]        # the tick's own work, hot and cold
    python benchmarks/tick_count.py breakdown [--parts a,b]  # where the walking tick's go
    python benchmarks/tick_count.py vision [--frames 5]      # per 320×240 frame: JPEG, ball
    python benchmarks/tick_count.py guard                    # CI: within 3 % of the record?
    python benchmarks/tick_count.py record                   # record this interpreter's figure
    python benchmarks/tick_count.py calibrate                # measured ÷ modelled, on this CPU
    python benchmarks/tick_count.py daemon [--window 800]    # the whole daemon, every thread

Each mode runs itself again under ``valgrind --tool=callgrind`` with the Z530's caches (32 KB
8-way L1i, 24 KB 6-way L1d, 512 KB 8-way L2, 64-byte lines: Intel's Z5xx datasheet) and counts
exactly the ticks it is asked for: the child zeroes, toggles and dumps callgrind's counts at the
start and end of each tick through client requests (``callgrind_requests.py``), so start-up,
imports and warm-up ticks are never counted. Counts repeat to ±0.1 % whatever the machine's
load: a figure from a loaded two-core VM is the figure of a quiet robot.

- ``tick``: ``Daemon._one_tick`` and the loop's bookkeeping, walking, with the bus answering
  from replies recorded off the emulator and a publisher that encodes every message it is handed
  (joints and IMU each tick, status at 10 Hz) but puts nothing: the daemon's own Python, no
  Zenoh, no waiting. **hot**: ticks back to back; **cold**: each tick after a sweep that leaves
  every cache empty (64 KB of code run, 2 MB of data moved), as after a deep C-state.

- ``vision``: per 320×240 camera frame, a JPEG passed through as a message, a raw frame
  encoded to JPEG, a JPEG decoded for vision, and ``BallFinder.find`` (every thread OpenCV
  uses is counted); the share printed is of a 30 fps frame period.

The model (``z530_us``): time = Ir × CPI + L1 misses × 15 cycles + L2 misses × 200 cycles, at
1.6 GHz. Sources and uncertainty in docs/loop-cpu.md; ``calibrate`` measures the ratio of thread
CPU to modelled time on the machine it runs on (on the robot: the model's correction factor).

- ``daemon``: the whole daemon (``darwin daemon`` on an emulator, every thread: the loop,
  publishing, the arbiter, Zenoh's own), walking with one client subscribed to the joints,
  counted over ``--window`` ticks of its walk (instructions only, no cache model), per tick.
  valgrind cannot keep 125 Hz, and a loop left to run as fast as valgrind lets it spreads what
  comes by the second (status, the bus-master check, lease renewals) over however many ticks
  valgrind's pace gave (±13 % from run to run): so the counted daemon ticks at ``--tick-ms``
  (50: a pace valgrind keeps) and each of those rates is slowed by the same factor, so it comes
  once per as many ticks as on the robot at 8 ms (``daemon_config``). It prints the rate the
  loop kept, its overruns and the status messages counted.

``--python`` runs the child under another interpreter. In the i386 root the whole script runs
inside the root with its Python (valgrind installed there with apt), as docs/loop-cpu.md shows.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import ctypes
import gc
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from callgrind_requests import Callgrind  # noqa: E402

# Intel Atom Z5xx datasheet (document 319535): 32 KB 8-way L1i, 24 KB 6-way L1d, 512 KB 8-way
# L2, 64-byte lines.
ATOM_CACHES = ["--I1=32768,8,64", "--D1=24576,6,64", "--LL=524288,8,64"]
CLOCK_HZ = 1.6e9  # Z530
CPI = 1.0  # cycles per instruction before misses: assumed (0.8–1.5, docs/loop-cpu.md)
L1_MISS_CYCLES = 15  # L2 hit latency (Intel's Atom optimisation guide, Agner Fog: 15–16)
L2_MISS_CYCLES = 200  # DRAM through the 533 MT/s FSB: ~100–125 ns at 1.6 GHz
EVENTS = ("Ir", "Dr", "Dw", "I1mr", "D1mr", "D1mw", "ILmr", "DLmr", "DLmw")
TICK_S = 0.008
STATUS_EVERY = 12.5  # ticks between status messages at 10 Hz


@dataclass
class Count:
    """Events per unit (a tick, a frame) over ``units`` units."""

    name: str
    units: int
    ir: float
    l1_misses: float
    ll_misses: float

    @classmethod
    def from_events(cls, name: str, units: int, ev: dict[str, int]) -> Count:
        l1 = ev.get("I1mr", 0) + ev.get("D1mr", 0) + ev.get("D1mw", 0)
        ll = ev.get("ILmr", 0) + ev.get("DLmr", 0) + ev.get("DLmw", 0)
        n = max(1, units)
        return cls(name, units, ev.get("Ir", 0) / n, l1 / n, ll / n)

    def minus(self, other: Count) -> Count:
        return Count(self.name, self.units, self.ir - other.ir, self.l1_misses - other.l1_misses,
                     self.ll_misses - other.ll_misses)

    def z530_us(self, cpi: float = CPI) -> float:
        cycles = self.ir * cpi + self.l1_misses * L1_MISS_CYCLES + self.ll_misses * L2_MISS_CYCLES
        return cycles / CLOCK_HZ * 1e6

    def line(self, period_ms: float | None = 8.0) -> str:
        us = self.z530_us()
        share = f"  {us / (period_ms * 10):5.1f} % of {period_ms:g} ms" if period_ms else ""
        return (f"{self.name:34}{self.ir / 1e3:10.1f} k Ir{self.l1_misses:9.0f} L1m"
                f"{self.ll_misses:8.0f} LLm {us:8.0f} µs Z530{share}")


# -- parsing callgrind's output --------------------------------------------------------------


def parts(out_prefix: Path) -> dict[str, dict[str, int]]:
    """Each dump's label → its event totals (callgrind.out.N files of one run)."""
    found: dict[str, dict[str, int]] = {}
    for path in sorted(out_prefix.parent.glob(out_prefix.name + "*")):
        text = path.read_text(errors="replace")
        trigger = re.search(r"^desc: Trigger: Client Request: (.+)$", text, re.M)
        events = re.search(r"^events: (.+)$", text, re.M)
        totals = re.search(r"^totals: (.+)$", text, re.M) or re.search(r"^summary: (.+)$",
                                                                       text, re.M)
        if not (trigger and events and totals):
            continue
        values = [int(v) for v in totals.group(1).split()]
        names = events.group(1).split()
        found[trigger.group(1).strip()] = dict(zip(names, values + [0] * len(names), strict=False))
    return found


def valgrind(child: list[str], python: str, out: Path, instr_at_start: bool = False) -> None:
    if shutil.which("valgrind") is None:
        raise SystemExit("tick_count: valgrind is not installed: apt-get install valgrind")
    cmd = [
        "valgrind", "--tool=callgrind", "--cache-sim=yes", *ATOM_CACHES,
        "--collect-atstart=no", f"--instr-atstart={'yes' if instr_at_start else 'no'}",
        f"--callgrind-out-file={out}", "--log-file=" + str(out) + ".log",
        python, str(Path(__file__).resolve()), *child,
    ]
    env = dict(os.environ, PYTHONHASHSEED="0", PYTHONDONTWRITEBYTECODE="1")
    proc = subprocess.run(cmd, env=env, cwd=ROOT)
    if proc.returncode != 0:
        log = Path(str(out) + ".log")
        tail = log.read_text(errors="replace").splitlines()[-5:] if log.exists() else []
        raise SystemExit(f"tick_count: the counted child failed ({proc.returncode}): {tail}")


# -- the tick's own work ------------------------------------------------------------------------


class _CountingPublisher:
    """The daemon's publisher without Zenoh: every message handed to it is encoded, as the
    motion thread (joints, IMU) and the publisher thread (status, events) would, and dropped."""

    def __init__(self) -> None:
        from robot_daemon.engine.broadcast import as_payload

        self.encode = as_payload  # what Publishers encodes with
        self.dropped_events = 0

    def wanted(self, topic: str) -> bool:
        return True

    def send(self, topic: str, msg: Any) -> None:
        self.encode(msg)

    def send_payload(self, topic: str, payload: bytes) -> None:
        pass

    def post(self, topic: str, msg: Any) -> None:
        self.encode(msg)

    def event(self, kind: str, message: str, **data: Any) -> None:
        from schemas.messages import Event

        self.encode(Event(kind=kind, message=message, data=data, seq=0))


class _NoCommands:
    counts: dict[str, int] = {}

    def has_pending(self) -> bool:
        return False


def tick_daemon(walking: bool = True, seconds: float = 3.0) -> Any:
    """A Daemon whose bus answers from recorded replies (benchmarks/tick_hot_cold.py's rig)."""
    from tick_hot_cold import walking_rig

    from config.loader import load_all, robot_from_dict
    from robot_daemon.engine.daemon import Daemon, DaemonOptions
    from robot_daemon.engine.power_actions import PowerGuard
    from robot_daemon.motion.fall import FallMonitor

    rig, _ = walking_rig(walking, seconds)
    settings = copy.deepcopy(rig.settings)
    daemon = Daemon(DaemonOptions(robot="count", port="replay", listen=[]),
                    robot_from_dict(settings["robot"]), settings)
    del load_all
    daemon.bus = rig.bus
    daemon.bus.emit = daemon.bus.sensors.emit = daemon._emit
    daemon.manager = rig.manager
    fall = rig.manager.get("fall")
    daemon.fall = fall if isinstance(fall, FallMonitor) else None
    daemon.guard = PowerGuard(daemon.robot, settings, daemon.manager, daemon.bus, daemon._emit)
    supervisor = getattr(daemon, "supervisor", None)  # the bus's lifecycle, where it has one
    if supervisor is not None:
        supervisor.bus, supervisor.manager, supervisor.guard = rig.bus, rig.manager, daemon.guard
    daemon.pub = _CountingPublisher()
    daemon.arbiter = _NoCommands()
    daemon._last_status = 0.0
    daemon._motion_thread = __import__("threading").current_thread()
    daemon.clock = 0.0
    if hasattr(daemon, "status_sources"):  # status at 10 Hz, as start_network would set it
        from robot_daemon.engine.broadcast import StatusSources, network_info

        daemon.status_sources = StatusSources(
            robot=daemon.robot, name="count", protocol=daemon.protocol,
            network=network_info(None, []), lease=daemon.lease, manager=daemon.manager,
            bus=daemon.bus, stats=daemon.stats, guard=daemon.guard,
            telemetry_hz=daemon.telemetry.hz, arbiter=None,
        )
    return daemon


def one_tick(daemon: Any) -> None:
    """What ``Daemon._loop`` does around a tick, on a simulated clock (8 ms a tick)."""
    start = daemon.clock
    bus_s = daemon._one_tick(start)
    daemon.stats.tick(start, bus_s, 0.001)
    daemon.clock = start + TICK_S


class Sweep:
    """Leaves every cache empty, as a deep C-state does: 64 KB of straight-line code run (twice
    the L1i) and 2 MB of data moved (four times the L2)."""

    def __init__(self) -> None:
        import mmap

        size = 64 * 1024
        self._code = mmap.mmap(-1, size + mmap.PAGESIZE,
                               prot=mmap.PROT_READ | mmap.PROT_WRITE | mmap.PROT_EXEC)
        self._code.write(b"\x90" * size + b"\xc3")  # nop … ret
        addr = ctypes.addressof(ctypes.c_char.from_buffer(self._code))
        self._run = ctypes.CFUNCTYPE(None)(addr)
        self._a = ctypes.create_string_buffer(1 << 20)
        self._b = ctypes.create_string_buffer(1 << 20)

    def __call__(self) -> None:
        self._run()
        ctypes.memmove(self._b, self._a, len(self._a))
        ctypes.memmove(self._a, self._b, len(self._a))


def child_tick(args: argparse.Namespace) -> None:
    cg = Callgrind()
    for walking in (True, False):
        daemon = tick_daemon(walking)
        # As Daemon.run does before its loop: the rig's start-up garbage frozen, so a full
        # collection of it cannot land inside a counted tick (one did, in the standing ticks).
        gc.collect()
        gc.freeze()
        what = "walking" if walking else "standing"
        sweep = Sweep()
        cg.start_instrumentation()
        for _ in range(args.warm):
            one_tick(daemon)
        # The requests' own cost, to take off each measured tick.
        cg.toggle()
        cg.toggle()
        cg.dump(f"overhead {what}")
        cg.toggle()
        for _ in range(args.ticks):
            one_tick(daemon)
        cg.toggle()
        cg.dump(f"hot {what}")
        for _ in range(args.ticks):
            sweep()
            cg.toggle()
            one_tick(daemon)
            cg.toggle()
        cg.dump(f"cold {what}")
        cg.stop_instrumentation()


# What ``breakdown`` counts: where the walking tick's instructions go (each name is resolved in
# the counted daemon; a module-level function is wrapped where the caller looks it up).
BREAKDOWN = (
    "bus.read_sensors", "bus.dxl.bulk_read", "bus.frame", "manager.step",
    "walking.step", "walking._pose", "gait.leg_servo_angles", "gait.gyro_feedback",
    "bus.write_targets", "daemon._publish", "daemon.joints_encoder.encode", "engine.imu_payload",
    "engine.status_message", "engine.take", "pub.encode", "daemon._update_state", "stats.tick",
)


def _resolve(daemon: Any, name: str) -> tuple[Any, str]:
    import robot_daemon.bus.dxl as dxl
    import robot_daemon.engine.broadcast as broadcast
    import robot_daemon.engine.daemon as engine
    import robot_daemon.motion.walking.gait as gait

    where = {"daemon": daemon, "bus": daemon.bus, "manager": daemon.manager, "engine": engine,
             "dxl": dxl, "gait": gait, "walking": daemon.manager.module("walking"),
             "pub": daemon.pub, "stats": daemon.stats, "broadcast": broadcast,
             "port": daemon.bus.handler, "supervisor": getattr(daemon, "supervisor", None)}
    head, *path, attr = name.split(".")
    if head == "module":  # module.<name>.<method>: a motion module by its name
        head, path = path[0], path[1:]
        where[head] = daemon.manager.module(head)
    obj = where[head]
    for part in path:
        obj = getattr(obj, part)
    return obj, attr


def breakdown_parts(args: argparse.Namespace) -> tuple[str, ...]:
    return tuple(args.parts.split(",")) if args.parts else BREAKDOWN


def counting(cg: Callgrind, fn: Any) -> Any:
    """``fn``, counted by callgrind while it runs (and only then)."""

    def wrapper(*a: Any, **kw: Any) -> Any:
        cg.toggle()
        try:
            return fn(*a, **kw)
        finally:
            cg.toggle()

    return wrapper


def child_breakdown(args: argparse.Namespace) -> None:
    cg = Callgrind()
    daemon = tick_daemon(True)
    cg.start_instrumentation()
    for _ in range(args.warm):
        one_tick(daemon)

    def counted(fn: Any) -> Any:
        return counting(cg, fn)

    def empty() -> None:
        pass

    wrapped_empty = counted(empty)
    for _ in range(args.ticks):
        wrapped_empty()
    cg.dump("overhead")
    for name in breakdown_parts(args):
        obj, attr = _resolve(daemon, name)
        original = getattr(obj, attr)
        setattr(obj, attr, counted(original))
        calls = 0
        for _ in range(args.ticks):
            one_tick(daemon)
        setattr(obj, attr, original)
        cg.dump(name)
        del calls
    cg.stop_instrumentation()


def count_breakdown(args: argparse.Namespace, out_dir: Path) -> list[Count]:
    out = out_dir / "breakdown.out"
    child = ["child-breakdown", "--ticks", str(args.ticks), "--warm", str(args.warm)]
    valgrind(child + (["--parts", args.parts] if args.parts else []), args.python, out)
    found = parts(out)
    over = Count.from_events("", args.ticks, found["overhead"])
    return [Count.from_events(n, args.ticks, found[n]) for n in breakdown_parts(args)] + [over]


# The guard's recorded figures: hot walking tick, instructions, by interpreter (callgrind counts
# depend on the Python build and numpy, not on the machine's load or speed).
RECORDED = Path(__file__).with_name("tick_count_recorded.json")
GUARD_SLACK = 0.03  # a tick may grow this much over its recorded figure


def guard_key() -> str:
    """The interpreter and which hot path the tick runs (robot_daemon/hotpath.py): the
    compiled one counts fewer instructions, and each has its own figure."""
    from robot_daemon import hotpath

    return f"{interpreter()}, hot path {'compiled' if hotpath.compiled else 'Python'}"


def child_guard(args: argparse.Namespace) -> None:
    cg = Callgrind()
    daemon = tick_daemon(True, seconds=1.0)
    cg.start_instrumentation()
    for _ in range(args.warm):
        one_tick(daemon)
    cg.toggle()
    for _ in range(args.ticks):
        one_tick(daemon)
    cg.toggle()
    cg.dump("guard")
    cg.stop_instrumentation()


def count_guard(args: argparse.Namespace, out_dir: Path) -> Count:
    out = out_dir / "guard.out"
    valgrind(["child-guard", "--ticks", str(args.ticks), "--warm", str(args.warm)],
             args.python, out)
    return Count.from_events("tick hot, walking", args.ticks, parts(out)["guard"])


# -- the camera and ball vision, per frame --------------------------------------------------------

VISION_PARTS = ("jpeg passthrough", "jpeg encode", "jpeg decode", "ball finder")


def vision_frame() -> Any:
    """A 320×240 BGR frame of a green field with a red ball (the finder's colour) and a red
    stripe it must turn down, with sensor noise so the JPEG is a camera's size."""
    import numpy as np

    rng = np.random.default_rng(1)
    img = np.empty((240, 320, 3), np.uint8)
    img[:] = (40, 140, 50)
    yy, xx = np.mgrid[0:240, 0:320]
    img[(xx - 210) ** 2 + (yy - 150) ** 2 < 18**2] = (20, 20, 210)
    img[20:26, 10:300] = (25, 25, 200)
    noise = rng.integers(-12, 13, img.shape)
    return np.clip(img.astype(int) + noise, 0, 255).astype(np.uint8)


def child_vision(args: argparse.Namespace) -> None:
    from config.loader import load_all
    from robot_daemon.vision.ball_finder import BallFinder, FinderSettings
    from robot_daemon.vision.opencv import decode_jpeg, encode_jpeg
    from schemas.messages import CameraFrame, encode

    cg = Callgrind()
    finder = BallFinder(FinderSettings.from_config(load_all().get("ballplay", {})))
    frame = vision_frame()
    jpeg = encode_jpeg(frame, 80)
    work = {
        "jpeg passthrough": lambda: encode(CameraFrame(jpeg=jpeg, width=320, height=240, seq=1)),
        "jpeg encode": lambda: encode_jpeg(frame, 80),
        "jpeg decode": lambda: decode_jpeg(jpeg),
        "ball finder": lambda: finder.find(frame),
    }
    if not finder.find(frame).found:
        raise SystemExit("tick_count: the finder does not see the benchmark's ball")
    cg.start_instrumentation()
    for name in VISION_PARTS:
        for _ in range(3):
            work[name]()
        cg.toggle()
        for _ in range(args.frames):
            work[name]()
        cg.toggle()
        cg.dump(name)
    cg.stop_instrumentation()


def count_vision(args: argparse.Namespace, out_dir: Path) -> list[Count]:
    out = out_dir / "vision.out"
    valgrind(["child-vision", "--frames", str(args.frames)], args.python, out)
    found = parts(out)
    return [Count.from_events(f"{name}, 320x240", args.frames, found[name])
            for name in VISION_PARTS]


def count_tick(args: argparse.Namespace, out_dir: Path) -> list[Count]:
    out = out_dir / "tick.out"
    valgrind(["child-tick", "--ticks", str(args.ticks), "--warm", str(args.warm)],
             args.python, out)
    found = parts(out)
    counts = []
    for what in ("walking", "standing"):
        over = Count.from_events("", 1, found[f"overhead {what}"])
        for kind in ("hot", "cold"):
            c = Count.from_events(f"tick {kind}, {what}", args.ticks, found[f"{kind} {what}"])
            counts.append(c.minus(over) if kind == "cold" else c)
    return counts


# -- entry -----------------------------------------------------------------------------------


def interpreter() -> str:
    import platform

    import numpy

    bits = 64 if sys.maxsize > 2**32 else 32
    return (f"{platform.machine()} {bits}-bit Python {platform.python_version()}, "
            f"numpy {numpy.__version__}")


CHILDREN = ("child-tick", "child-breakdown", "child-guard", "child-vision", "child-daemon")


def guard(args: argparse.Namespace) -> int:
    """``guard``: fail (exit 1, one line) when the hot walking tick counts more than
    GUARD_SLACK over the figure recorded for this interpreter; ``record``: record it."""
    with tempfile.TemporaryDirectory(prefix="tick-count-") as tmp:
        got = count_guard(args, Path(tmp))
    key = f"{guard_key()}; {args.ticks} ticks after {args.warm}"
    recorded = json.loads(RECORDED.read_text()) if RECORDED.exists() else {}
    if args.mode == "record":
        recorded[key] = round(got.ir)
        RECORDED.write_text(json.dumps(recorded, indent=1, sort_keys=True) + "\n")
        print(f"tick_count: recorded {got.ir / 1e3:.1f} k instructions a tick for {key}")
        return 0
    figure = recorded.get(key)
    if figure is None:
        print(f"tick_count: no figure recorded for {key}: run `tick_count.py record` on it")
        return 2
    growth = got.ir / figure - 1
    verdict = "over" if growth > GUARD_SLACK else "within"
    print(f"tick_count: {got.ir / 1e3:.1f} k instructions a tick, {growth * 100:+.1f} % of the "
          f"recorded {figure / 1e3:.1f} k ({verdict} the {GUARD_SLACK * 100:g} % allowed; {key})")
    return 1 if growth > GUARD_SLACK else 0


def calibrate(args: argparse.Namespace) -> int:
    """The model against this CPU: the hot walking tick counted (callgrind) and timed (thread
    CPU, no valgrind), and their ratio. On a real Bonnell (the robot's Atom) the ratio is the
    model's correction factor; the CPI that would explain the time is printed beside it."""
    with tempfile.TemporaryDirectory(prefix="tick-count-") as tmp:
        counted = count_guard(args, Path(tmp))
    daemon = tick_daemon(True, seconds=1.0)
    for _ in range(args.warm):
        one_tick(daemon)
    n = max(500, args.ticks * 50)
    t0 = time.thread_time()
    for _ in range(n):
        one_tick(daemon)
    measured_us = (time.thread_time() - t0) / n * 1e6
    modelled_us = counted.z530_us()
    misses_us = counted.z530_us(cpi=0.0)
    cpi = max(0.0, (measured_us - misses_us) * CLOCK_HZ / 1e6 / counted.ir)
    print(f"{interpreter()}: hot walking tick {counted.ir / 1e3:.1f} k instructions; measured "
          f"{measured_us:.0f} µs of thread CPU a tick here, Z530 model {modelled_us:.0f} µs: "
          f"measured ÷ modelled = {measured_us / modelled_us:.2f} (at 1.6 GHz that is CPI "
          f"{cpi:.2f} besides the misses)")
    return 0


# What the daemon does by the second, not by the tick. Under valgrind its loop cannot keep
# 125 Hz, and how fast it does run depends on the machine's load: left on the clock, status,
# the bus-master check's /proc walk and the lease's renewals would come once per as many ticks
# as valgrind's pace gave (the count moved ±13 % from run to run). So ``daemon`` drives each of
# them by the loop's ticks, on the robot's clock (8 ms a tick) and the daemon's own rules:
# status 10 Hz (once per 13 ticks, as the daemon's test `now - last >= 0.1` gives at 8 ms),
# the status's loop percentiles refreshed every 0.5 s, the /proc walk every 2 s (250 ticks)
# where it goes by the clock (on Linux it runs when the port is opened or closed, so not in a
# count), a
# lease renewal every 0.25 s (31.25 ticks, sent by the counting client). What stays on the
# clock: Zenoh's own timers and keep-alives (~0.1 M instructions a second on i386: ~4 k a tick
# at valgrind's 20 ticks a second where 125 Hz would make it ~0.7 k, so the figure is high by
# that much), and valgrind's overruns judged over the loop's 2 s windows, whose overload alarm
# (an event and a status each) is the machine's, not the robot's, so it is kept quiet.
ROBOT_TICK_S = 0.008
LINK_LEASE_MS = 60_000


def child_daemon(argv: list[str]) -> int:
    """``darwin daemon`` as it runs, with what it does by the second driven by its ticks."""
    from robot_daemon.bus.preflight import HolderWatch
    from robot_daemon.engine.daemon import Daemon
    from robot_daemon.engine.loop_stats import LoopStats
    from robot_daemon.launch.cli import main as darwin

    publish = Daemon._publish
    summary = LoopStats.summary
    run_holders = HolderWatch._run
    kicks: dict[int, threading.Event] = {}

    def publish_by_ticks(self: Any, snap: Any, now: float) -> None:
        robot_now = self.tick * ROBOT_TICK_S  # the robot's clock: 8 ms a tick
        if math.isfinite(self.status_period):  # no status by the clock: by the robot's below
            self._robot_period, self.status_period = self.status_period, math.inf
            self._robot_last = robot_now
        if self._status_dirty or robot_now - self._robot_last >= self._robot_period:
            self._status_dirty = True  # _publish's own test, on the robot's clock
            self._robot_last = robot_now
        publish(self, snap, now)
        watch = self.supervisor.holders
        if (
            watch is not None
            and not watch.by_event
            and self.tick % round(watch.interval / ROBOT_TICK_S) == 0
        ):
            kicks.setdefault(id(watch), threading.Event()).set()

    def summary_by_ticks(self: LoopStats, max_age: float = 0.5, now: float | None = None
                         ) -> dict[str, Any]:
        return summary(self, max_age, self.ticks * ROBOT_TICK_S)

    def judge_quietly(self: LoopStats) -> None:
        # valgrind's overruns are not the robot's: no overload alarm, no event and no status
        # of its own for them (the overruns are still counted, and printed).
        self._win_ticks = self._win_overruns = 0

    def walk_when_kicked(self: HolderWatch) -> None:  # HolderWatch._run's, kicked
        if self.by_event:
            return run_holders(self)  # it looks when the port is opened or closed: as it runs
        kick = kicks.setdefault(id(self), threading.Event())
        while not self._stop.is_set():
            kick.wait()
            kick.clear()
            self._walk()

    Daemon._publish = publish_by_ticks  # type: ignore[method-assign]
    LoopStats.summary = summary_by_ticks  # type: ignore[method-assign]
    LoopStats._judge = judge_quietly  # type: ignore[method-assign]
    HolderWatch._run = walk_when_kicked  # type: ignore[method-assign]
    if os.environ.get(PARTS_ENV):
        count_daemon_parts(Daemon, LoopStats, os.environ[PARTS_ENV].split(","),
                           int(os.environ[WINDOW_ENV]))
    return darwin(["daemon", *argv])


# ``daemon --parts``: where the motion thread's instructions go in the running daemon.
PARTS_ENV, WINDOW_ENV, PARTS_DONE = "DARWIN_COUNT_PARTS", "DARWIN_COUNT_WINDOW", "parts counted"


def count_daemon_parts(daemon_cls: Any, stats_cls: Any, names: list[str], window: int) -> None:
    """From SIGUSR1 on (the walk under way), count in the motion thread only, ``window`` ticks
    each: the whole thread, then each named part (a callable wrapped so that it alone is
    counted: callgrind's collection state is the calling thread's), a dump each. Parts are
    switched between ticks (after ``LoopStats.tick``), never inside one."""
    import signal

    cg = Callgrind()
    go = threading.Event()
    signal.signal(signal.SIGUSR1, lambda *_: go.set())
    queue = ["motion thread", *names]
    now: dict[str, Any] = {"part": None, "left": 0, "undo": None}
    stats_tick = stats_cls.tick
    daemons: list[Any] = []
    publish = daemon_cls._publish

    def remember(self: Any, snap: Any, t: float) -> None:
        if not daemons:
            daemons.append(self)
        publish(self, snap, t)

    def counted(fn: Any) -> Any:
        return counting(cg, fn)

    def tick_and_switch(self: Any, start: float, bus_s: float, work_s: float) -> None:
        stats_tick(self, start, bus_s, work_s)
        if not go.is_set() or not daemons or (not queue and now["part"] is None):
            return
        if now["part"] is None:
            if now["left"] == 0 and queue[0] == "motion thread":  # the first: set up
                cg.start_instrumentation()
                cg.toggle()  # this thread's collection off: only what is asked is counted
            part = now["part"] = queue.pop(0)
            now["left"] = window
            if part == "motion thread":
                cg.toggle()
            else:
                obj, attr = _resolve(daemons[0], part)
                original = getattr(obj, attr)
                setattr(obj, attr, counted(original))
                now["undo"] = (obj, attr, original)
            return
        now["left"] -= 1
        if now["left"] > 0:
            return
        if now["part"] == "motion thread":
            cg.toggle()
        else:
            obj, attr, original = now["undo"]
            setattr(obj, attr, original)
        cg.dump(now["part"])
        now["part"] = None
        if not queue:
            cg.stop_instrumentation()
            print(f"tick_count: {PARTS_DONE}", flush=True)

    daemon_cls._publish = remember
    stats_cls.tick = tick_and_switch


def count_daemon(args: argparse.Namespace) -> int:
    """``daemon``: instructions per tick of the whole daemon process, walking (see above)."""
    from benchmarks.loop_cpu import SIM_MARGIN_MS, emulator
    from clients.lease_keeper import RENEW_PERIOD
    from clients.robot import Robot
    from schemas.errors import DarwinError
    from schemas.session import free_tcp_port, open_client

    for tool in ("valgrind", "callgrind_control"):
        if shutil.which(tool) is None:
            raise SystemExit(f"tick_count: {tool} is not installed: apt-get install valgrind")
    robot_ticks_per_renewal = RENEW_PERIOD / ROBOT_TICK_S
    with tempfile.TemporaryDirectory(prefix="tick-count-") as tmp, emulator(0.0) as port:
        out = Path(tmp) / "daemon.out"
        cfg = Path(tmp) / "daemon.toml"
        # valgrind runs one thread at a time (no real-time loop); the lease never ends on a
        # slow arbiter (its renewals still come: below), nor the link on Zenoh's threads
        # starved by valgrind on a loaded machine (the client's liveliness token, hence the
        # lease, went with it: a long link lease on both sides).
        cfg.write_text(f"[daemon]\nrealtime_priority = 0\ntick_ms = {args.tick_ms:g}\n"
                       "[daemon.lease]\nheartbeat_timeout = 0\nidle_timeout = 0\n"
                       f"[zenoh]\nlink_lease_ms = {LINK_LEASE_MS}\n")
        endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
        cmd = ["valgrind", "--tool=callgrind", "--instr-atstart=no", "--separate-threads=yes",
               f"--callgrind-out-file={out}", f"--log-file={out}.log", args.python,
               str(Path(__file__).resolve()), "child-daemon", "--port", port, "--camera", "none",
               "--listen", endpoint, "--robot", "count", "--config", str(cfg),
               "--reply-margin-ms", SIM_MARGIN_MS]
        env = dict(os.environ, PYTHONHASHSEED="0", PYTHONDONTWRITEBYTECODE="1")
        if args.parts:
            env.update({PARTS_ENV: args.parts, WINDOW_ENV: str(args.window)})
        proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
        ticks: list[int] = []
        statuses: list[dict[str, Any]] = []
        got_tick = threading.Condition()
        renew = threading.Event()
        renewals = 0
        lost: list[str] = []
        events: list[tuple[str, list[int]]] = []  # (kind, the last tick seen then)

        def joints(m: Any) -> None:
            with got_tick:
                if ticks and int(m.tick / robot_ticks_per_renewal) != int(
                        ticks[-1] / robot_ticks_per_renewal):
                    renew.set()
                ticks.append(m.tick)
                got_tick.notify_all()

        def renewing(robot: Robot, done: threading.Event) -> None:
            nonlocal renewals
            while True:
                renew.wait()
                renew.clear()
                if done.is_set():
                    return
                try:
                    robot.command("lease", timeout=30.0, op="renew")
                except DarwinError as exc:  # the lease was lost: said below
                    lost.append(str(exc))
                    return
                renewals += 1

        def wait_tick(n: int) -> int:
            """Until a joints message of tick ``n`` or later came; its tick."""
            with got_tick:
                if not got_tick.wait_for(lambda: bool(ticks) and ticks[-1] >= n, timeout=600):
                    raise SystemExit(f"tick_count: the daemon did not reach tick {n} in 600 s")
                return ticks[-1]

        try:
            assert proc.stdout is not None
            for line in proc.stdout:
                if line.startswith("zenoh:"):
                    break
            else:
                raise SystemExit(f"tick_count: the daemon exited ({proc.wait()}): see {out}.log")
            session = open_client(endpoint, lease_ms=LINK_LEASE_MS)
            with session, Robot(endpoint, "count", name="tick_count", session=session) as robot:
                robot.wait_for("status", lambda s: s.loop["ticks"] > 50, timeout=600)
                robot.acquire()
                # The holder's renewals by the daemon's ticks (renewing), not by the clock.
                robot._lease.period = 1e6
                done = threading.Event()
                renewer = threading.Thread(target=renewing, args=(robot, done), daemon=True)
                renewer.start()
                robot.walk(x=0.05)
                with robot.subscribe("joints", joints), \
                        robot.subscribe("status", lambda s: statuses.append(
                            {**s.loop, "held": s.lease is not None})), \
                        robot.subscribe("events", lambda e: events.append((e.kind, ticks[-1:]))):
                    wait_tick(0)
                    wait_tick(ticks[-1] + round(5000 / args.tick_ms))  # the walk under way
                    control = ["callgrind_control", str(proc.pid)]
                    first, t0, s0, r0 = ticks[-1], time.monotonic(), len(statuses), renewals
                    loop0 = statuses[-1] if statuses else {}
                    if args.parts:  # the daemon counts them itself (count_daemon_parts)
                        proc.send_signal(signal.SIGUSR1)
                        assert proc.stdout is not None
                        if not any(PARTS_DONE in line for line in proc.stdout):
                            raise SystemExit(f"tick_count: the daemon exited ({proc.wait()})")
                    else:
                        subprocess.run([*control[:1], "-i", "on", *control[1:]], check=True,
                                       capture_output=True, timeout=120)
                        first = ticks[-1]
                        wait_tick(first + args.window)
                        subprocess.run([*control[:1], "-d", *control[1:]], check=True,
                                       capture_output=True, timeout=120)
                    last, elapsed = ticks[-1], time.monotonic() - t0
                    s1, r1 = len(statuses), renewals
                    loop1 = statuses[-1] if statuses else {}
                done.set()
                renew.set()
                renewer.join()
                with contextlib.suppress(DarwinError):  # counted already; a slow daemon may
                    robot.walk_stop()  # not answer in time, and is stopped below anyway
                    robot.release()
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=120)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        if args.parts:
            found = {}
            for path in Path(tmp).glob("daemon.out.*-01"):  # the motion thread's, per dump
                text = path.read_text(errors="replace")
                label = re.search(r"^desc: Trigger: Client Request: (.+)$", text, re.M)
                totals = re.search(r"^(?:totals|summary): (\d+)", text, re.M)
                if label and totals:
                    found[label.group(1).strip()] = int(totals.group(1))
        threads = []
        for path in sorted(Path(tmp).glob("daemon.out.1-*")):
            totals = re.search(r"^(?:totals|summary): (\d+)", path.read_text(errors="replace"),
                               re.M)
            if totals:
                threads.append(int(totals.group(1)))
        if args.keep:  # callgrind's per-thread profiles, for callgrind_annotate
            Path(args.keep).mkdir(parents=True, exist_ok=True)
            for path in Path(tmp).glob("daemon.out*"):
                shutil.copy2(path, Path(args.keep) / path.name)
    if args.parts:
        print(f"{interpreter()}; callgrind; the daemon's motion thread walking at a "
              f"{args.tick_ms:g} ms tick, {args.window} ticks a part (each call counted pays "
              "the counting's own ~7 k)")
        for name in ["motion thread", *args.parts.split(",")]:
            if name in found:
                print(f"{name:40}{found[name] / args.window / 1e3:10.1f} k instructions a tick")
        if lost:
            print(f"(the lease was lost meanwhile: {lost[0]})")
        return 0
    if lost or not all(s["held"] for s in statuses[s0:s1]):
        # A loaded machine can starve the daemon's Zenoh threads under valgrind until the
        # client's session (and with it the lease and the walk) is dropped.
        raise SystemExit(f"tick_count: the lease was lost during the count ({lost[:1]}): the "
                         "robot stopped walking; count again on a less loaded machine")
    n = max(1, last - first)
    total = sum(threads)
    # Events in the window (a servo's reply missed under valgrind's delays goes offline and
    # back: an event and a status each, the machine's cost rather than the robot's).
    kinds = Counter(k for k, at in events if at and first < at[0] <= last)
    top = max(threads, default=0)
    overruns = loop1.get("overruns", 0) - loop0.get("overruns", 0)
    print(f"{interpreter()}; callgrind, every thread; the daemon walking at a {args.tick_ms:g} ms "
          f"tick, {n} ticks in {elapsed:.0f} s ({n / elapsed:.1f} ticks/s, {overruns} overruns); "
          f"by its ticks, {s1 - s0} status messages (one per {n / max(1, s1 - s0):.1f} ticks) "
          f"and {r1 - r0} lease renewals (one per {n / max(1, r1 - r0):.1f}); events: "
          f"{', '.join(f'{k} {c}' for k, c in sorted(kinds.items())) or 'none'}")
    print(f"whole daemon: {total / n / 1e3:.1f} k instructions a tick ({len(threads)} threads; "
          f"the busiest {top / n / 1e3:.1f} k, the others {(total - top) / n / 1e3:.1f} k)")
    return 0


def main() -> int:
    if sys.argv[1:2] == ["child-daemon"]:  # the rest are the daemon's own options
        return child_daemon(sys.argv[2:])
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("mode", choices=["tick", "breakdown", "vision", "guard", "record",
                                         "calibrate", "daemon", *CHILDREN])
    parser.add_argument("--frames", type=int, default=5, help="camera frames counted per part")
    parser.add_argument("--ticks", type=int, default=40, help="ticks counted per figure")
    parser.add_argument("--warm", type=int, default=60, help="ticks run before counting")
    parser.add_argument("--parts", help="breakdown, daemon: only these parts (comma-separated "
                        "names as BREAKDOWN spells them, e.g. bus.frame,engine.take)")
    parser.add_argument("--python", default=sys.executable, help="the interpreter to count")
    parser.add_argument("--json", help="also write the figures here")
    parser.add_argument("--window", type=int, default=800,
                        help="daemon: the ticks of its walk counted")
    parser.add_argument("--tick-ms", type=float, default=50.0,
                        help="daemon: its tick under valgrind (a pace valgrind keeps)")
    parser.add_argument("--keep", help="daemon: keep callgrind's per-thread profiles here")
    args = parser.parse_args()
    if args.mode == "child-tick":
        child_tick(args)
        return 0
    if args.mode == "child-breakdown":
        child_breakdown(args)
        return 0
    if args.mode == "child-guard":
        child_guard(args)
        return 0
    if args.mode == "child-vision":
        child_vision(args)
        return 0
    if args.mode in ("guard", "record"):
        return guard(args)
    if args.mode == "calibrate":
        return calibrate(args)
    if args.mode == "daemon":
        return count_daemon(args)
    with tempfile.TemporaryDirectory(prefix="tick-count-") as tmp:
        out_dir = Path(tmp)
        t0 = time.monotonic()
        counts: list[Count] = []
        if args.mode == "tick":
            counts += count_tick(args, out_dir)
        if args.mode == "breakdown":
            counts += count_breakdown(args, out_dir)
        if args.mode == "vision":
            counts += count_vision(args, out_dir)
        print(f"{interpreter()}; callgrind, Z530 caches; per tick ({time.monotonic() - t0:.0f} s)")
        for c in counts:
            print(c.line(33.3 if args.mode == "vision" else 8.0))
        if args.json:
            Path(args.json).write_text(json.dumps([asdict(c) for c in counts], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
