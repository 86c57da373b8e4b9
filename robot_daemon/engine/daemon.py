"""The robot daemon: the 8 ms motion loop, publication on the key space, the arbiter.

One motion thread owns the bus. Each tick, at an absolute deadline: bulk-read the sensors,
apply queued commands, run the motion modules, sync-write the goals, put the joints and IMU
(droppable) and hand status and events to the publisher thread. A lost port is reopened with
back-off while ``status.state`` says so.

Safety rules the loop keeps: whenever the control lease ends (released, holder gone, idle) the
motion comes to a safe stop; losing the port halts every motion module, commands that need the
bus are refused with ``unavailable`` until it is back, and then the robot holds the pose it is
in until someone commands it; every shutdown halts the motion and holds the pose before the bus
is let go.

Beside it: the bus's bring-up, power, loss and return and the buttons (``bus_lifecycle.py``,
a :class:`BusSupervisor` the daemon is composed of), the messages it publishes
(``broadcast.py``), its Zenoh session (``zenoh_setup.py``), its states
(``schemas/daemon_state.py``).
"""

from __future__ import annotations

import contextlib
import gc
import logging
import os
import threading
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import zenoh

from config.loader import RobotConfig, refuse_unknown, shipped
from robot_daemon import hotpath
from robot_daemon.arbiter.core import Arbiter
from robot_daemon.arbiter.lease import Holder, Lease
from robot_daemon.arbiter.registry import MotionContext
from robot_daemon.arbiter.throttle import ArbiterLimits
from robot_daemon.bus.robot_bus import RobotBus
from robot_daemon.engine.broadcast import (
    JointsEncoder,
    LoopFacts,
    StatusSources,
    imu_payload,
    network_info,
    status_message,
)
from robot_daemon.engine.bus_lifecycle import BusSupervisor, Buttons
from robot_daemon.engine.loop_stats import LoopStats
from robot_daemon.engine.policy_link import PolicyLink, link_policy
from robot_daemon.engine.power_actions import PowerGuard
from robot_daemon.engine.publishers import Publishers
from robot_daemon.engine.snapshot import TickSnapshot, take
from robot_daemon.engine.telemetry_rate import RateGate, check_rate
from robot_daemon.engine.zenoh_setup import open_session
from robot_daemon.frames import JointFrame, Targets
from robot_daemon.motion.fall import FallMonitor
from robot_daemon.motion.setup import build_manager
from robot_daemon.realtime import (
    check_latency,
    check_priority,
    current_policy,
    enter_realtime,
    hold_cpu_latency,
)
from robot_daemon.security.acl import Security, serve_roles
from robot_daemon.services import DaemonInfo
from schemas.daemon_state import DaemonState
from schemas.errors import BusError, PortError
from schemas.keys import Keys
from schemas.session import Credentials
from schemas.versions import PACKAGE_VERSION, announced_protocol, fmt

if TYPE_CHECKING:
    from robot_daemon.engine.camera import CameraThread

log = logging.getLogger(__name__)

# Motion time follows the clock (a late tick moves the gait on by the time that passed), but a
# stall longer than this many periods counts as this many: the gait must not jump.
MAX_DT_TICKS = 4.0
# The longest a stop waits for a walk's last step (half a gait period: 0.3 s at the stock 600 ms),
# well inside the boot service's TimeoutStopSec.
STOP_FINISH_S = 2.0
# A gap between ticks this long is the daemon's own stall, not its lease holder's silence.
LEASE_STALL_S = 0.1


@dataclass
class DaemonOptions:
    """How a daemon runs: its robot name and port, where it listens and whom it joins, its tick and
    camera."""

    robot: str
    port: str
    listen: list[str]
    tick_ms: float = 8.0
    camera: str = "none"
    allow_eeprom: bool = False
    connect: list[str] = field(default_factory=list)  # peers to join, e.g. the emulator's
    router: str | None = None  # a Zenoh router to join (`--router`): the fleet's meeting point
    extras: dict[str, Any] = field(default_factory=dict)
    security: Security | None = None  # --auth/--secure: authentication, TLS, access control
    credentials: Credentials | None = None  # who this robot is to its router (--user…)


class Daemon:
    def __init__(self, options: DaemonOptions, robot: RobotConfig, settings: dict[str, Any]):
        self.options = options
        self.robot = robot
        self.settings = settings
        dcfg = settings.get("daemon", {})
        # A misspelt setting must not leave its default silently in force.
        refuse_unknown(dcfg, shipped().get("daemon", {}), "daemon")
        self.keys = Keys(options.robot)
        self.tick_s = options.tick_ms / 1000.0
        self.status_period = 1.0 / float(dcfg.get("status_hz", 10.0))
        self.telemetry = RateGate(
            check_rate(dcfg.get("telemetry_hz", 0.0), "daemon.telemetry_hz"), self.tick_s
        )
        self.realtime_priority = check_priority(
            dcfg.get("realtime_priority", 0), "daemon.realtime_priority"
        )
        self.cpu_latency_us = check_latency(
            dcfg.get("cpu_dma_latency_us", -1), "daemon.cpu_dma_latency_us"
        )
        self._latency_fd: int | None = None
        self.scheduling = "other"
        self.state = DaemonState.STARTING
        self.stats = LoopStats(self.tick_s, emit=self._emit)
        self.manager = build_manager(robot, settings)
        self.bus = RobotBus(options.port, robot, settings, self._emit)
        fall = self.manager.get("fall")
        self.fall = fall if isinstance(fall, FallMonitor) else None  # the one fall detector
        self.info = DaemonInfo(robot=options.robot, tick_ms=options.tick_ms)
        self.protocol = announced_protocol()
        self.guard = PowerGuard(robot, settings, self.manager, self.bus, self._emit)
        self.supervisor = BusSupervisor(
            self.bus,
            self.manager,
            self.guard,
            self._emit,
            self._set_state,
            backoff_min=float(dcfg.get("reopen_backoff_min", 0.1)),
            backoff_max=float(dcfg.get("reopen_backoff_max", 5.0)),
            buttons=Buttons.from_config(dcfg.get("buttons")),
            holder_check_s=float(dcfg.get("holder_check_s", 2.0)),
        )
        self.tick = 0
        self.bus_errors = 0
        self.frame: JointFrame | None = None
        self.snapshot: TickSnapshot | None = None  # the last tick's, every message's source
        self.joints_encoder = JointsEncoder(robot)
        self.status_sources: StatusSources | None = None
        self._sampled_at = time.time()
        self._stop = threading.Event()
        # Held until stop() lets it go: the loop paces itself by waiting for it (one C call; an
        # Event's wait is a Condition's, in Python: ~15 k instructions a tick on the robot's
        # Python, docs/loop-cpu.md).
        self._stop_gate = threading.Lock()
        self._stop_gate.acquire()
        self._stop_lock = threading.Lock()  # stop() from two threads releases the gate once
        self._stop_by: float | None = None  # after stop(): the walk's last step ends by then
        self._wake = threading.Event()  # a command arrived (the port-lost wait ends at once)
        self._safe_stop = threading.Event()
        self._status_dirty = True
        self._last_start: float | None = None  # start of the previous tick, for its real dt
        self._motion_thread: threading.Thread | None = None
        self.camera: CameraThread | None = None
        self.policy_link: PolicyLink | None = None
        self.session: zenoh.Session | None = None
        self.pub: Publishers | None = None
        self.arbiter: Arbiter | None = None
        self.lease = Lease.from_config(dcfg.get("lease", {}), on_change=self._lease_changed)
        self.arbiter_limits = ArbiterLimits.from_config(dcfg.get("arbiter", {}))
        self._early_events: list[tuple[str, str, dict[str, Any]]] = []

    # -- events and lease --------------------------------------------------------------------
    def _emit(self, kind: str, message: str, **data: Any) -> None:
        if self.pub is None:
            self._early_events.append((kind, message, data))
        else:
            self.pub.event(kind, message, **data)
        if kind.startswith(("servo_", "loop_")):
            self._status_dirty = True

    def _lease_changed(self, old: Holder | None, new: Holder | None, reason: str) -> None:
        # Who may have motion started for them (robot_daemon/motion_authority.py): a fall is
        # recovered from only inside the lease holder's motion.
        self.manager.controller = new.client if new is not None else None
        if new is not None:
            self._emit("lease", f"lease acquired by {new.name!r}", holder=new.to_dict())
        else:
            who = old.name if old else "?"
            # Control ended without its holder asking: in the daemon's log too, since why it
            # ended (silent, vanished, idle) is what an operator asks afterwards.
            level = logging.INFO if reason == "released" else logging.WARNING
            log.log(level, "lease of %r (client %s) ended: %s", who,
                    old.client if old else "?", reason)  # fmt: skip
            self._emit("lease", f"lease of {who!r} ended: {reason}", holder=None, reason=reason)
            # Whatever ended it (released, vanished, idle), nobody controls the motion it
            # started any more: a safe stop (a walk ends its step). In the motion thread (a
            # `lease release` command, the idle check) at once, so a command queued after it
            # in the same tick is not stopped; from elsewhere at the next tick.
            if threading.current_thread() is self._motion_thread:
                self.manager.stop_all()
            else:
                self._safe_stop.set()
        self._status_dirty = True

    def _set_state(self, state: DaemonState) -> None:
        if state != self.state:
            log.info("daemon state: %s → %s", self.state, state)
            self.state = state
            self._status_dirty = True
            if self.pub is not None:
                self.pub.event("state", f"daemon {state}", state=str(state))

    # -- lifecycle ---------------------------------------------------------------------------
    def start_network(self) -> None:
        self.session = open_session(
            self.options.listen,
            self.settings.get("zenoh", {}),
            router=self.options.router,
            connect=self.options.connect,
            credentials=self.options.credentials,
            security=self.options.security,
        )
        self.pub = Publishers(self.session, self.keys)
        for kind, message, data in self._early_events:
            self.pub.event(kind, message, **data)
        self._early_events.clear()
        self.arbiter = Arbiter(self.session, self.keys, self.lease, limits=self.arbiter_limits)
        self.arbiter.gate = self.supervisor.gate
        self.arbiter.on_wakeup = self._wake.set
        self._alive = self.session.liveliness().declare_token(self.keys.alive)
        self._alive_version = self.session.liveliness().declare_token(
            self.keys.alive_version(fmt(self.protocol), PACKAGE_VERSION)
        )
        self._roles = serve_roles(self.session, self.keys)
        self.policy_link = link_policy(self.session, self.keys, self.manager, self.pub, self)
        if self.options.camera != "none":
            from robot_daemon.engine.camera import CameraThread

            self.camera = CameraThread.from_settings(
                self.session, self.keys, self.options.camera, self.settings
            )
        self.status_sources = StatusSources(
            robot=self.robot,
            name=self.options.robot,
            protocol=self.protocol,
            network=network_info(self.options.router, self.options.listen),
            lease=self.lease,
            manager=self.manager,
            bus=self.bus,
            stats=self.stats,
            guard=self.guard,
            telemetry_hz=self.telemetry.hz,
            camera=self.camera,
            arbiter=self.arbiter,
        )

    def connect_bus(self) -> None:
        """Open the port, power the servos, scan, hold the present pose (the first start)."""
        self.supervisor.connect(first=True)
        self._update_state()

    def _update_state(self, snap: TickSnapshot | None = None) -> None:
        if self.supervisor.stopping:
            return  # stopping stays stopping until the daemon is gone
        if self.supervisor.servos_off:
            self._set_state(DaemonState.SERVOS_OFF)
            return
        online = snap.online if snap is not None else self.bus.state.online.tolist()
        healthy = self.bus.cm730_online and all(self.joints_encoder.pick(online))
        self._set_state(DaemonState.RUNNING if healthy else DaemonState.DEGRADED)

    def stop(self) -> None:
        with self._stop_lock:
            if not self._stop.is_set():
                self._stop.set()
                self._stop_gate.release()
        self._wake.set()

    def close(self) -> None:
        """Halt the motion and hold the pose, then let go of everything (the bus last)."""
        self._set_state(DaemonState.STOPPING)
        self.supervisor.halt_and_hold(self.tick, self.tick_s)
        self._drain_events()
        self._publish_status(time.monotonic())
        if self._latency_fd is not None:  # the CPU may sleep deeply again
            os.close(self._latency_fd)
            self._latency_fd = None
        if self.camera is not None:
            self.camera.close()
        if self.arbiter is not None:
            self.arbiter.close()
        if self.policy_link is not None:
            self.policy_link.close()
        with contextlib.suppress(Exception):
            self._alive.undeclare()
            self._alive_version.undeclare()
        if self.pub is not None:
            self.pub.close()
        self.bus.close()
        if self.session is not None:
            with contextlib.suppress(Exception):
                self.session.close()

    # -- the loop ----------------------------------------------------------------------------
    def run(self) -> None:
        """Run until :meth:`stop`; the caller's thread becomes the motion thread."""
        self._last_status = 0.0
        self._motion_thread = threading.current_thread()
        warning = enter_realtime(self.realtime_priority)
        if warning:
            log.warning("%s", warning)
            self._emit("warning", warning)
        self.scheduling = current_policy()
        self._latency_fd, warning = hold_cpu_latency(self.cpu_latency_us)
        if warning:
            log.warning("%s", warning)
            self._emit("warning", warning)
        # Start-up's objects (modules, configs, the Zenoh session) are frozen out of the
        # collector once, here where a pause hurts nobody: a full collection in the loop then
        # scans only what came after (a few k instructions instead of ~10 M, two ticks of the
        # Atom), and start-up's garbage is not left for the loop to collect (docs/loop-cpu.md).
        gc.collect()
        gc.freeze()
        # compiled, or why not (robot_daemon/hotpath.py): a missing compiler is this one line
        (log.warning if hotpath.missing else log.info)("%s", hotpath.status)
        while not self._stop.is_set():
            if not self.bus.is_open:
                self._reconnect()
                continue
            try:
                if self.supervisor.power_request is not None:
                    self.supervisor.repower()  # outside the timed loop: it waits ~0.36 s
                    self._update_state()
                self._loop()
            except PortError as exc:
                if self._stop.is_set():
                    return  # shutting down: the emulator may simply have stopped first
                self.supervisor.port_lost(exc)
            except Exception as exc:
                # A failure nobody foresaw must not end the daemon: report it, start the bus
                # over as if the port had gone.
                log.exception("the motion loop failed")
                if self._stop.is_set():
                    return
                self.supervisor.port_lost(exc)

    def _reconnect(self) -> None:
        """Try to reopen the port; while it fails, keep answering commands and status."""
        wait = self.supervisor.try_reopen()
        if wait is None:
            self._update_state()
            return
        deadline = time.monotonic() + wait
        while not self._stop.is_set() and time.monotonic() < deadline:
            self._wake.clear()
            if self.arbiter is not None:
                # Answered at once: refused (the gate) or done without the bus (halt, lease).
                self.arbiter.apply_pending(self._context(self.frame))
            if self.lease.expire():
                self._status_dirty = True
            self._drain_events()
            self._publish_status(time.monotonic())
            self._wake.wait(min(self.status_period, max(0.0, deadline - time.monotonic())))

    def _drain_events(self) -> None:
        for kind, message, data in self.manager.drain_events():
            self._emit(kind, message, **data)

    def _loop(self) -> None:
        next_deadline = time.monotonic()
        self._last_start = None
        self.stats.reset_period()
        # Powering the servos (the verb, START) leaves the loop: it is done outside its timing.
        while self.supervisor.power_request is None and self._ticking():
            start = time.monotonic()
            try:
                bus_s = self._one_tick(start)
            except PortError:
                raise
            except BusError as exc:
                # A transaction that failed as a whole (not one device): count it, go on.
                self.bus_errors += 1
                log.warning("bus error in tick %d: %s", self.tick, exc)
                bus_s = time.monotonic() - start
            work = time.monotonic() - start
            self.stats.tick(start, bus_s, work)
            next_deadline += self.tick_s
            now = time.monotonic()
            if now > next_deadline:
                # Overrun: start the next tick now and re-anchor the schedule there, rather
                # than burst through the missed deadlines to catch up.
                self.stats.overrun(int((now - next_deadline) / self.tick_s))
                next_deadline = now
            delay = max(0.0, next_deadline - time.monotonic())
            if self._stop.is_set():
                time.sleep(delay)  # the walk's last step, paced as every tick
            elif self._stop_gate.acquire(timeout=delay):
                self._stop_gate.release()  # stopped: left free for whoever waits next

    def _ticking(self) -> bool:
        """Whether the loop ticks on: until :meth:`stop`, and after it while a walk ends its
        step. Stopped at once (a service stop, Ctrl-C) a walk would stand on one foot, the
        swing foot in the air, and tip over: as the ``halt`` verb, it ends at its next double
        support (at most half a gait period; ``STOP_FINISH_S`` bounds it) and then the pose is
        held (:meth:`close`)."""
        if not self._stop.is_set():
            return True
        if self._stop_by is None:
            self._stop_by = time.monotonic() + STOP_FINISH_S
            self.supervisor.stopping = True  # no command starts anything from here on
            self._set_state(DaemonState.STOPPING)
            if not any(m.in_motion for m in self.manager.modules):
                return False
            self.manager.halt(finish_step=True)
            self._drain_events()
        finishing = any(m.finishing for m in self.manager.modules)
        return finishing and time.monotonic() < self._stop_by

    def _one_tick(self, start: float) -> float:
        """One tick; returns the time spent on the bus."""
        bus_t0 = time.monotonic()
        self.bus.read_sensors()
        supervisor = self.supervisor
        supervisor.check_power()  # DXL power gone: halted, servos off until asked
        supervisor.check_buttons()
        supervisor.check_holders()
        bus_read = time.monotonic() - bus_t0
        # Stamp the data when it was sampled, not when the tick got round to publishing it, so
        # stamp differences are the sampling interval whatever the tick's work took.
        self._sampled_at = time.time()
        self.tick += 1
        # Motion time is the time that passed (bounded), so late ticks do not slow the gait.
        last, self._last_start = self._last_start, start
        dt = self.tick_s if last is None else min(start - last, MAX_DT_TICKS * self.tick_s)
        if last is not None and start - last > LEASE_STALL_S:
            # The loop did not run: a holder's renewals of that time are still in the queue.
            self.lease.excuse(start - last - self.tick_s)
        frame = self.bus.frame(self.tick, start, dt)
        self.frame = frame
        if self._safe_stop.is_set():
            self._safe_stop.clear()
            self.manager.stop_all()
        supervisor.hold_if_back(frame)
        assert self.arbiter is not None
        if self.arbiter.has_pending():  # most ticks have no command: no context to build
            self.arbiter.apply_pending(self._context(frame))
        try:
            targets = self.manager.step(frame)
        except Exception as exc:
            # A motion module bug must not kill the loop: stop everything and hold the pose.
            log.exception("motion step failed")
            self._emit("fault", f"motion step failed: {exc!r}; halted")
            self.manager.halt()
            targets = Targets()
        bus_t1 = time.monotonic()
        self.bus.write_targets(targets)
        bus_write = time.monotonic() - bus_t1
        fall = self.fall.direction if self.fall is not None else "none"
        self.snapshot = snap = take(self.bus, frame, self._sampled_at, self.tick, fall)
        self._publish(snap, start)
        return bus_read + bus_write

    def _context(self, frame: JointFrame | None) -> MotionContext:
        return MotionContext(
            robot=self.robot,
            manager=self.manager,
            bus=self.bus,
            settings=self.settings,
            frame=frame,
            emit=self._emit,
            lease=self.lease,
            camera=self.camera,
            publish=self.pub.post if self.pub is not None else None,
            info=self.info,
            extras={"allow_eeprom": self.options.allow_eeprom, **self.options.extras},
            power=self.supervisor,
        )

    # -- publication -------------------------------------------------------------------------
    def _publish(self, snap: TickSnapshot, now: float) -> None:
        assert self.pub is not None
        for kind, message, data in self.manager.drain_events():
            self.pub.event(kind, message, **data)
        # Built only for someone: a message nobody subscribes to costs the tick for nothing.
        # Sent from this thread, after the goals are written (publishers.py says why).
        if self.telemetry.open(now):
            if self.pub.wanted("joints"):
                self.pub.send_payload("joints", self.joints_encoder.encode(snap))
            if self.pub.wanted("imu"):
                self.pub.send_payload("imu", imu_payload(snap))
        self._update_state(snap)
        # Every tick (a lock and a clock read): a silent holder's lease ends within one tick of
        # heartbeat_timeout after its last renewal, so a cut link stops the robot within it.
        if self.lease.expire():
            self._status_dirty = True
        if self._status_dirty or now - self._last_status >= self.status_period:
            # The battery and heat policy at the status rate (10 Hz), not per tick.
            cm_voltage = self.bus.cm730_status()["voltage"]
            self.guard.check(cm_voltage, snap.temperature, snap.online, now)
            self._publish_status(now, snap)

    def _publish_status(self, now: float, snap: TickSnapshot | None = None) -> None:
        if self.pub is None or self.status_sources is None:
            return
        self._status_dirty = False
        self._last_status = now
        if snap is None and self.frame is not None:  # outside a tick: the bus as it is now
            fall = self.fall.direction if self.fall is not None else "none"
            snap = take(self.bus, self.frame, self._sampled_at, self.tick, fall)
        facts = LoopFacts(
            state=str(self.state),
            bus_errors=self.bus_errors,
            scheduling=self.scheduling,
            events_dropped=self.pub.dropped_events,
        )
        self.pub.post("status", status_message(self.status_sources, snap, facts))
