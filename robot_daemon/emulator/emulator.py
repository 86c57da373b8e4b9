"""The hardware emulator: the simulated bus served on a pseudo-terminal, in a thread of its own.

    with Emulator(EmulatorSettings(wire_timing=False)) as emu:
        port = PortHandler(emu.port)        # dynamixel-sdk, exactly as on the robot

One thread blocks in ``select`` on the pty (and a wake-up pipe), parses what arrives, lets the
:class:`~robot_daemon.emulator.servo_chain.Bus` answer, and writes the replies when a 1 Mbps
wire would have delivered them. Time (``emulator/clock.py``): with ``realtime`` the servos
advance to "now" before every packet, and a physics thread runs the physics hooks every
``idle_step_s`` (only while there are hooks), in a quiet moment of the bus when a host is
polling it; without it, only :meth:`advance` moves time (a simulated clock can then run faster
than real time). Every public method is thread-safe.

The seam for the simulated world (``robot_daemon/plant``): :meth:`add_physics_hook` gets
``fn(dt, emulator)`` after every physics step (at most ``max_step_s`` long), and inside it the
world reads :meth:`present_positions` / :meth:`goal_positions` and feeds back
:meth:`set_body_motion` (and :meth:`set_present_position` for limp joints). Hooks run without
the emulator's lock, so the bus keeps answering while they compute.
"""

from __future__ import annotations

import contextlib
import logging
import os
import select
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from robot_daemon.bus.packet import PACKET_OVERHEAD, BadChecksum, Frame, PacketParser
from robot_daemon.bus.tables import Instruction
from robot_daemon.emulator import bringup
from robot_daemon.emulator.api import EmulatorApi
from robot_daemon.emulator.clock import EmulatorClock, PhysicsHook
from robot_daemon.emulator.devices import Environment
from robot_daemon.emulator.faults import Faults
from robot_daemon.emulator.ftdi import FtdiChip
from robot_daemon.emulator.pty_link import PtyLink
from robot_daemon.emulator.servo_chain import Bus
from robot_daemon.emulator.settings import EmulatorSettings
from robot_daemon.realtime import check_priority, enter_realtime

log = logging.getLogger(__name__)

_EARLY = 50e-6  # write a reply this close to its due time rather than sleep again


class Emulator:
    def __init__(self, settings: EmulatorSettings | None = None, **overrides: Any) -> None:
        s = settings or EmulatorSettings()
        for key, value in overrides.items():
            if not hasattr(s, key):
                raise TypeError(f"Emulator got an unknown setting {key!r}")
            setattr(s, key, value)
        check_priority(s.realtime_priority, "emulator realtime_priority")
        check_priority(s.physics_priority, "emulator physics_priority")
        self.settings = s
        # A fresh SeedSequence's entropy is an int (typed wider, for a given one).
        self.seed = s.seed or int(np.random.SeedSequence().entropy % 2**32)  # type: ignore[operator]
        self.rng = np.random.default_rng(self.seed)
        self.lock = threading.RLock()
        self.env = Environment(s.voltage, s.ambient_c, s.heat_gain_c, s.thermal_tau_s)
        self.bus = Bus(
            self.rng,
            self.env,
            imu_noise=s.imu_noise,
            gyro_full_scale_dps=s.gyro_full_scale_dps,
            power_on_delay_s=s.power_on_delay_s,
            initial_positions=s.initial_positions,
        )
        self.faults = Faults(s.drop, s.corrupt, s.delay, s.delay_ms)
        self.stats: dict[str, int] = dict.fromkeys(
            (
                "rx_bytes",
                "frames",
                "bad_checksums",
                "replies",
                "dropped",
                "corrupted",
                "delayed",
                "collisions",
                "overflow_bytes",
            ),
            0,
        )
        # The run-time API (the world's seam, faults and inputs, inspection): emu.api.
        self.api = EmulatorApi(self.lock, self.bus, self.env, self.faults, self.seed, self.stats)
        self.api.set_voltage(s.voltage)  # checks the range
        for dxl_id in s.silent_ids:
            self.api.silence(dxl_id)
        self.bus.cm730_late_reads = s.cm730_late_reads
        bringup.apply(self.bus, s)
        for dxl_id in s.overheat_ids:
            self.api.overheat(dxl_id)
        self.bus.line_bps = s.baud
        self.bus.break_chain(s.broken_after)
        if s.fresh_servo:
            self.bus.factory_fresh(s.fresh_servo)
        self.wire_timing = s.wire_timing
        self.byte_time_s = 10.0 / s.baud
        self.link = PtyLink(s.link, s.baud)
        # ftdi_latency_ms > 0: replies reach the pty as an FTDI chip delivers them.
        latency = s.ftdi_latency_ms / 1000
        self.ftdi = FtdiChip(self.byte_time_s, latency) if latency else None
        self.parser = PacketParser()
        self.received: deque[Frame] = deque(maxlen=1000)
        self._out: deque[tuple[float, bytes]] = deque()
        self._bus_free = 0.0
        self._last_rx = 0.0
        self._thread: threading.Thread | None = None
        self._physics_thread: threading.Thread | None = None
        self._quiet = threading.Event()  # set when no reply is due and no packet half-read
        self._stopping = threading.Event()
        self.clock = EmulatorClock(
            self, self.lock, self.bus, s, self._stopping, self._quiet, lambda: self._last_rx
        )
        self._wake_r = self._wake_w = -1  # a pipe that wakes the thread, made by start()
        self._served = threading.Condition(self.lock)
        self._waiting = 0  # threads in wait_quiet/wait_stat: only they need _served notified

    # ---- time (the clock's) ----------------------------------------------------------------

    def add_physics_hook(self, fn: PhysicsHook) -> None:
        """Call ``fn(dt, emulator)`` with every physics step of the clock."""
        self.clock.add_physics_hook(fn)

    def remove_physics_hook(self, fn: PhysicsHook) -> None:
        self.clock.remove_physics_hook(fn)

    def advance(self, dt: float) -> None:
        """Step the dynamics by ``dt`` seconds now (in steps of at most ``max_step_s``)."""
        self.clock.advance(dt)

    @property
    def sim_time(self) -> float:
        return self.clock.sim_time

    # ---- lifecycle --------------------------------------------------------------------------

    @property
    def port(self) -> str:
        """The path a client opens (the ``link`` symlink if one was asked for)."""
        return self.link.path

    def start(self) -> Emulator:
        if self._thread is not None:
            raise RuntimeError("this Emulator is already running; create another one")
        self.link.open()
        self._wake_r, self._wake_w = os.pipe()
        self.clock.restart()
        self._thread = threading.Thread(target=self._serve, name="darwin-sim-bus", daemon=True)
        self._thread.start()
        if self.settings.realtime:
            self._physics_thread = threading.Thread(
                target=self._run_physics, name="darwin-sim-physics", daemon=True
            )
            self._physics_thread.start()
        log.info("emulator on %s (seed %d)", self.port, self.seed)
        return self

    def stop(self) -> None:
        self._stopping.set()
        self.clock.release()
        self._quiet.set()
        self._wake()
        for thread in (self._thread, self._physics_thread):
            if thread is not None:
                thread.join(timeout=5)
        self._thread = self._physics_thread = None
        with self.lock:
            self.link.close()
        for fd in (self._wake_r, self._wake_w):
            if fd >= 0:
                os.close(fd)
        self._wake_r = self._wake_w = -1

    def __enter__(self) -> Emulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _wake(self) -> None:
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")

    # ---- the port vanishing ------------------------------------------------------------------

    def vanish(self) -> None:
        """Close the pty and remove the link: clients lose the port."""
        with self.lock:
            self.link.close()
            self.parser.reset()
            self._out.clear()
        self._wake()

    def reappear(self) -> str:
        """A new pty (relinked if there is a link); returns the path to open."""
        with self.lock:
            self.link.open()
        self._wake()
        return self.port

    def _bus_quiet(self) -> bool:
        return not self._out and not self.parser.pending

    # ---- the serving thread -----------------------------------------------------------------

    @staticmethod
    def _enter_realtime(priority: int, thread: str, setting: str) -> None:
        # Refused (no root, no rtprio limit), the thread runs normally: a line at -v.
        warning = enter_realtime(priority, f"the emulator's {thread} thread", setting)
        if warning:
            log.info("emulator: %s", warning)

    def _serve(self) -> None:
        self._enter_realtime(self.settings.realtime_priority, "bus", "emulator.realtime_priority")
        # Most wake-ups (a tick's USB packets falling due, ~4 a tick) only write: each takes
        # the lock once, and wakes nobody who is not waiting.
        with self.lock:
            fds, timeout = self._select_args()
        while not self._stopping.is_set():
            try:
                readable, _, _ = select.select(fds, [], [], timeout)
            except (OSError, ValueError):
                with self.lock:  # the pty was closed under us (vanish); look again
                    fds, timeout = self._select_args()
                continue
            if self._wake_r in readable:
                with contextlib.suppress(OSError):
                    os.read(self._wake_r, 512)
            with self.lock:
                try:
                    self._service(readable)
                except Exception:  # keep serving: a bug must not take the bus down
                    log.exception("emulator: error while serving the bus")
                if self._waiting:
                    self._served.notify_all()
                fds, timeout = self._select_args()

    def _run_physics(self) -> None:
        self._enter_realtime(self.settings.physics_priority, "physics", "emulator.physics_priority")
        self.clock.run_physics()

    def _select_args(self) -> tuple[list[int], float | None]:
        """What the serving thread waits on, and how long at most. Call with the lock held."""
        master = self.link.master
        fds = [self._wake_r] if master is None else [self._wake_r, master]
        return fds, self._timeout()

    def _timeout(self) -> float | None:
        # After every wake-up (~6 a tick): the earlier of the two waits, without a list or a
        # min and a max call.
        out, pending = self._out, self.parser.pending
        if not out and not pending:
            return None
        now = time.perf_counter()
        if out:
            wait = out[0][0] - now
            if pending:
                held = self._last_rx + self.settings.packet_timeout_s - now
                if held < wait:
                    wait = held
        else:
            wait = self._last_rx + self.settings.packet_timeout_s - now
        return wait if wait > 0.0 else 0.0

    def _service(self, readable: list[int]) -> None:
        master = self.link.master
        data = self.link.read() if master is not None and master in readable else b""
        # Most wake-ups (a tick's USB packets falling due, ~5 a tick) only write.
        if data or self.parser.pending:
            self._receive(data)
        self._flush()
        if not self._quiet.is_set() and self._bus_quiet():  # (set() wakes its waiters' lock)
            self._quiet.set()

    def _receive(self, data: bytes) -> None:
        """Answer what the host sent (``data``, or a packet held half-read timing out)."""
        if self.settings.realtime:
            # Only a packet can need the servos at "now". Most wake-ups just write a reply
            # that fell due (21 per bulk read), and stepping 20 servos on each of those was
            # most of the emulator's CPU, holding the GIL when replies were due.
            self.clock.sync_servos()
        if data:
            self._follow_line_rate()
            now = time.perf_counter()
            if self._out:  # the host talks while a reply is pending: they collide
                self.stats["collisions"] += len(self._out)
                self._out.clear()
                self._bus_free = now
            self.stats["rx_bytes"] += len(data)
            self._last_rx = now
            self._process(self.parser.feed(data), now)
        if self.parser.pending and (
            time.perf_counter() - self._last_rx >= self.settings.packet_timeout_s
        ):
            self._process(self.parser.expire(), time.perf_counter())

    def _follow_line_rate(self) -> None:
        """The devices hear the host at the rate its port is set to, and bytes take that
        long on the wire."""
        bps = self.link.baud() or self.settings.baud
        if bps != self.bus.line_bps:
            self.bus.set_line_bps(bps)
            self.byte_time_s = 10.0 / bps

    def _process(self, frames: list[Frame], t_rx: float) -> None:
        replies, self._bus_free = self._answer(frames, max(t_rx, self._bus_free), self.wire_timing)
        if self.ftdi is not None and replies:
            self.stats["replies"] += len(replies)
            replies = self.ftdi.deliver(replies)
        self._out.extend(replies)

    def _answer(
        self, frames: list[Frame], t: float, wire_timing: bool
    ) -> tuple[list[tuple[float, bytes]], float]:
        """What the devices send back for ``frames`` whose first byte arrived at ``t``: each
        reply with the time its last byte is on the line (faults applied), and the time the bus
        is free again. Call with the lock held."""
        out: list[tuple[float, bytes]] = []
        byte_s = self.byte_time_s
        for frame in frames:
            self.received.append(frame)
            self.stats["frames"] += 1
            if isinstance(frame, BadChecksum):
                self.stats["bad_checksums"] += 1
                size = len(frame.raw)
            else:
                size = len(frame.params) + PACKET_OVERHEAD
            if wire_timing:
                t += size * self.byte_time_s
            chain = frame.code == Instruction.BULK_READ and not isinstance(frame, BadChecksum)
            faults = self.faults if self.faults.active else None
            for reply in self.bus.handle(frame):
                if faults is not None:
                    packet, extra, fault = faults.apply(self.rng, reply.packet)
                    if fault:
                        self.stats[fault] += 1
                else:  # what apply gives with no fault set, without a call for each reply
                    packet, extra = reply.packet, 0.0
                if packet is None:
                    if chain:
                        break  # a bulk read's later devices wait for the lost status packet
                    continue
                if wire_timing:
                    t += reply.return_delay_s + len(packet) * byte_s
                if extra:
                    t += extra
                out.append((t, packet))
        return out, t

    def exchange(
        self, parser: PacketParser, data: bytes, t: float
    ) -> tuple[list[tuple[float, bytes]], float]:
        """The in-process link's way in
        (:class:`robot_daemon.emulator.inprocess_link.EmulatorLink`): bytes a host puts on the
        wire at ``t`` (the link's clock, s), framed by the link's own ``parser``; returns the
        replies, each with the time a 1 Mbps wire would have delivered it, and the time the wire
        is free again."""
        with self.lock:
            self.stats["rx_bytes"] += len(data)
            return self._answer(parser.feed(data), t, wire_timing=True)

    def _flush(self) -> None:
        if not self._out or self.link.master is None:
            return
        now = time.perf_counter()
        chunk = bytearray()
        while self._out and self._out[0][0] <= now + _EARLY:
            data = self._out.popleft()[1]
            if self.ftdi is not None:  # USB packets go one write each (replies were counted)
                self.stats["overflow_bytes"] += len(data) - self.link.write(data)
                continue
            chunk += data
            self.stats["replies"] += 1
        if chunk:
            written = self.link.write(bytes(chunk))
            self.stats["overflow_bytes"] += len(chunk) - written

    def wait_quiet(self, timeout: float = 5.0) -> bool:
        """Block until no partial packet is held and no reply waits to be sent."""
        return self._wait_served(lambda: not self.parser.pending and not self._out, timeout)

    def wait_stat(self, name: str, at_least: int, timeout: float = 5.0) -> bool:
        """Block until ``stats[name]`` reaches ``at_least``, e.g. until the emulator has taken
        a packet that gets no reply (``"frames"``) or sent one (``"replies"``)."""
        if name not in self.stats:
            raise KeyError(f"no emulator statistic {name!r}; known: {', '.join(self.stats)}")
        return self._wait_served(lambda: self.stats[name] >= at_least, timeout)

    def _wait_served(self, predicate: Callable[[], bool], timeout: float) -> bool:
        with self._served:
            self._waiting += 1
            try:
                return self._served.wait_for(predicate, timeout)
            finally:
                self._waiting -= 1
