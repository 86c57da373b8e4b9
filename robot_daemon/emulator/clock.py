"""The emulator's time: a simulated clock that only :meth:`EmulatorClock.advance` moves, or the
real clock, with the servos brought to "now" before every packet and a physics thread running
the hooks every ``idle_step_s`` in a quiet moment of the bus.

The :class:`~robot_daemon.emulator.emulator.Emulator` has one, made with only what it uses: the
lock, the servo chain, the settings, the serving thread's stop event, its "bus is quiet" event
and when the host last sent a byte.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from robot_daemon.emulator.emulator import Emulator
    from robot_daemon.emulator.servo_chain import Bus
    from robot_daemon.emulator.settings import EmulatorSettings

# Logged as the emulator: its lines keep the name they are filtered and read by.
log = logging.getLogger("robot_daemon.emulator.emulator")

PhysicsHook = Callable[[float, "Emulator"], None]
_MAX_CATCH_UP_S = 0.1
# A host that sent something this recently is polling: physics waits for a quiet moment.
_POLLING_S = 0.05


class EmulatorClock:
    def __init__(
        self,
        owner: Emulator,
        lock: threading.RLock,
        bus: Bus,
        settings: EmulatorSettings,
        stopping: threading.Event,
        quiet: threading.Event,
        last_rx: Callable[[], float],
    ) -> None:
        self._owner = owner  # what each physics hook is handed
        self.lock = lock
        self.bus = bus
        self.settings = settings
        self._stopping = stopping
        self._quiet = quiet  # set by the serving thread when no reply is due
        self._last_rx = last_rx  # perf_counter() of the host's last byte
        self._hooks: list[PhysicsHook] = []
        self._hook_failures = 0
        self._clock = time.monotonic()
        self._physics_wake = threading.Event()

    def add_physics_hook(self, fn: PhysicsHook) -> None:
        with self.lock:
            self._hooks.append(fn)
        self._physics_wake.set()

    def remove_physics_hook(self, fn: PhysicsHook) -> None:
        with self.lock:
            self._hooks.remove(fn)

    def advance(self, dt: float) -> None:
        """Step the dynamics by ``dt`` seconds now (in steps of at most ``max_step_s``)."""
        if dt < 0:
            raise ValueError(f"advance(dt={dt!r}): time only goes forward")
        remaining = dt
        while remaining > 1e-12:
            h = min(remaining, self.settings.max_step_s)
            with self.lock:
                self.bus.step(h)
            self._run_hooks(h)
            remaining -= h

    @property
    def sim_time(self) -> float:
        return self.bus.time

    def restart(self) -> None:
        """The serving thread starts: real time counts from now."""
        self._clock = time.monotonic()

    def release(self) -> None:
        """The emulator stops: a physics thread waiting for hooks or a quiet bus goes on."""
        self._physics_wake.set()

    def _run_hooks(self, dt: float) -> None:
        # Hooks run without the lock: the bus keeps answering while the world computes, and
        # the emulator methods a hook calls take the lock themselves.
        for hook in list(self._hooks):
            try:
                hook(dt, self._owner)
            except Exception:
                self._hook_failures += 1
                if self._hook_failures <= 3:
                    log.exception("emulator: physics hook %r failed", hook)

    def sync_servos(self) -> None:
        """Real-time clock: bring the servos to "now" (one exact step, cheap) before answering."""
        now = time.monotonic()
        dt, self._clock = now - self._clock, now
        if dt > 0:
            self.bus.step(dt)

    def run_physics(self) -> None:
        """Real-time clock: run the physics hooks every ``idle_step_s`` while there are any
        (the physics thread)."""
        last = time.monotonic()
        while not self._stopping.is_set():
            if not self._hooks:
                self._physics_wake.wait()
                self._physics_wake.clear()
                last = time.monotonic()
                continue
            if self._stopping.wait(self.settings.idle_step_s):
                return
            self._wait_for_quiet_bus()
            now = time.monotonic()
            # After a stall (a debugger, a loaded machine) the world skips time, not replays it.
            dt, last = min(now - last, _MAX_CATCH_UP_S), now
            with self.lock:
                self.sync_servos()
            while dt > 1e-12:
                h = min(dt, self.settings.max_step_s)
                self._run_hooks(h)
                dt -= h

    def _wait_for_quiet_bus(self) -> None:
        """A physics round is ~2 ms of Python holding the GIL; run mid-transaction, it would
        make replies late that the wire model says are due. A polling host leaves the bus
        quiet once each transaction is answered (after its sync write, or its last reply),
        so wait for the next such moment, but never longer than one more step."""
        with self.lock:
            if time.perf_counter() - self._last_rx() >= _POLLING_S:
                return
            # Not merely "quiet now": the host may be about to start its next transaction.
            self._quiet.clear()
        self._quiet.wait(self.settings.idle_step_s)
