"""The daemon's hold on the serial bus: bringing it up, losing it and getting it back, letting it
go at shutdown.

Losing the port halts every motion module; until it is back, commands that need the bus are
refused with ``unavailable`` while the rest (halt, lease, status) are still answered; the first
tick with the port back holds the pose the robot is in. Mixed into
:class:`~robot_daemon.engine.daemon.Daemon`, whose state it shares.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import TYPE_CHECKING

from robot_daemon.arbiter.registry import Reject, Request, needs_lease
from schemas.daemon_state import DaemonState
from schemas.errors import BusError, DxlPowerLostError, ErrorCode

if TYPE_CHECKING:
    from typing import Any

    from robot_daemon.arbiter.core import Arbiter
    from robot_daemon.arbiter.lease import Lease
    from robot_daemon.arbiter.registry import MotionContext
    from robot_daemon.bus.robot_bus import RobotBus
    from robot_daemon.engine.power_actions import PowerGuard
    from robot_daemon.engine.publishers import Publishers
    from robot_daemon.frames import JointFrame
    from robot_daemon.motion.manager import MotionManager

# The daemon's logger: these lines were always the daemon's, and logs are read by that name.
log = logging.getLogger("robot_daemon.engine.daemon")


class BusLifecycle:
    # The Daemon's, set in its __init__.
    bus: RobotBus
    manager: MotionManager
    guard: PowerGuard
    lease: Lease
    arbiter: Arbiter | None
    pub: Publishers | None
    frame: JointFrame | None
    tick: int
    tick_s: float
    status_period: float
    backoff_min: float
    backoff_max: float
    _backoff: float
    _bus_down: bool
    _hold_on_return: bool
    _status_dirty: bool
    _stop: threading.Event
    _wake: threading.Event

    if TYPE_CHECKING:

        def _emit(self, kind: str, message: str, **data: Any) -> None: ...
        def _set_state(self, state: DaemonState) -> None: ...
        def _update_state(self) -> None: ...
        def _context(self, frame: JointFrame | None) -> MotionContext: ...
        def _publish_status(self, now: float) -> None: ...

    def connect_bus(self) -> None:
        """Open the port, power the servos, scan, hold the present pose."""
        self._set_state(DaemonState.STARTING)
        self.bus.open()
        self._set_state(DaemonState.SCANNING)
        self.bus.power_on()
        found = self.bus.scan()
        log.info("found %d devices on %s: %s", len(found), self.bus.port_name, sorted(found))
        for w in self.bus.warnings:
            self._emit("warning", w)
        self.bus.initial_read()
        self.bus.read_sensors()
        self._update_state()

    def _halt_and_hold(self) -> None:
        """Every module stops now and the present pose is written as the goal, while the bus
        is still ours: no walk or page goes on (or freezes mid-stride) once nobody drives it."""
        self.manager.halt()
        if self.bus.is_open:
            try:
                self.bus.read_sensors()
                frame = self.bus.frame(self.tick + 1, time.monotonic(), self.tick_s)
                self.manager.hold_present(frame)
                self.bus.write_targets(self.manager.step(frame))
            except Exception as exc:  # a port already gone: nothing more to hold
                log.warning("holding the pose at shutdown failed: %s", exc)
        if self.pub is not None:
            for kind, message, data in self.manager.drain_events():
                self.pub.event(kind, message, **data)

    def _outage_gate(self, req: Request) -> None:
        """While the port is lost, refuse what needs the bus or moves the robot (halt, lease,
        config and stops still work): acknowledging it would run it when the port returns."""
        if self._bus_down and (req.verb == "registers" or needs_lease(req.verb, req.fields)):
            raise Reject(
                ErrorCode.UNAVAILABLE,
                f"the serial port {self.bus.port_name} is lost (status.state is port_lost): "
                f"{req.verb} not done; send it again once the port is back",
            )
        why = self.guard.refusal(req.verb, req.fields)
        if why is not None:
            raise Reject(ErrorCode.UNAVAILABLE, why)

    def _port_lost(self, exc: Exception) -> None:
        what = "" if isinstance(exc, DxlPowerLostError) else "serial port lost: "
        log.warning("%s%s", what, exc)
        self._emit(
            "fault", f"{what}{exc}; motion halted, reopening with back-off", port=self.bus.port_name
        )
        # Nothing that ran before the outage resumes after it: every module stops now, and
        # the first tick with the port back holds the pose the robot is in.
        self._bus_down = True
        self._hold_on_return = True
        self.manager.halt()
        self.bus.close()
        self.bus.counters.port_reopens += 1
        self._set_state(DaemonState.PORT_LOST)
        self._backoff = self.backoff_min

    def _reconnect(self) -> None:
        """Try to reopen the port; while it fails, keep answering commands and status."""
        backoff = getattr(self, "_backoff", self.backoff_min)
        try:
            self.connect_bus()
            self._bus_down = False
            self._emit("port", f"serial port {self.bus.port_name} is back; holding the pose")
            return
        except BusError as exc:
            log.info("reopening %s failed: %s", self.bus.port_name, exc)
            self.bus.close()
            self._set_state(DaemonState.PORT_LOST)
        deadline = time.monotonic() + backoff
        self._backoff = min(backoff * 2, self.backoff_max)
        while not self._stop.is_set() and time.monotonic() < deadline:
            self._wake.clear()
            if self.arbiter is not None:
                # Answered at once: refused (the gate) or done without the bus (halt, lease).
                self.arbiter.apply_pending(self._context(self.frame))
            if self.lease.expire():
                self._status_dirty = True
            for kind, message, data in self.manager.drain_events():
                self._emit(kind, message, **data)
            self._publish_status(time.monotonic())
            self._wake.wait(min(self.status_period, max(0.0, deadline - time.monotonic())))
