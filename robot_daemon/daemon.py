"""The robot daemon: the 8 ms motion loop, publication on the key space, the arbiter.

One motion thread owns the bus. Each tick, at an absolute deadline: bulk-read the sensors,
apply queued commands, run the motion modules, sync-write the goals, hand the messages to the
publisher thread. A lost port is reopened with back-off while ``status.state`` says so.

Safety rules the loop keeps: whenever the control lease ends (released, holder gone, idle) the
motion comes to a safe stop; losing the port halts every motion module, commands that need the
bus are refused with ``unavailable`` until it is back, and then the robot holds the pose it is
in until someone commands it; every shutdown halts the motion and holds the pose before the bus
is let go.
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
import time
from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING, Any

import numpy as np
import zenoh

from config.loader import RobotConfig
from robot_daemon.arbiter.core import Arbiter
from robot_daemon.arbiter.lease import Holder, Lease
from robot_daemon.arbiter.registry import MotionContext, Reject, Request, needs_lease
from robot_daemon.arbiter.throttle import ArbiterLimits
from robot_daemon.bus.power_watch import check_dxl_power
from robot_daemon.bus.robot_bus import RobotBus
from robot_daemon.fleet_join import ROUTER_CONNECT_TIMEOUT_MS, join_router
from robot_daemon.frames import JointFrame, Targets
from robot_daemon.loop_stats import LoopStats
from robot_daemon.motion.fall import FallMonitor
from robot_daemon.motion.setup import build_manager
from robot_daemon.policy_link import PolicyLink, link_policy
from robot_daemon.power_actions import PowerGuard
from robot_daemon.publishers import Publishers
from robot_daemon.realtime import check_priority, current_policy, enter_realtime
from robot_daemon.security.acl import Security, serve_roles
from robot_daemon.services import DaemonInfo
from schemas.errors import BusError, DarwinError, DxlPowerLostError, ErrorCode, PortError
from schemas.keys import Keys
from schemas.messages import Imu, Joints, NetworkInfo, Status
from schemas.session import MAX_MESSAGE_BYTES, Credentials, server_config
from schemas.versions import announced_protocol, fmt, package_version

if TYPE_CHECKING:
    from robot_daemon.camera import CameraThread

log = logging.getLogger(__name__)

# Motion time follows the clock (a late tick moves the gait on by the time that passed), but a
# stall longer than this many periods counts as this many: the gait must not jump.
MAX_DT_TICKS = 4.0


class ListenError(DarwinError):
    """The daemon cannot listen on its Zenoh endpoint."""


class DaemonState(StrEnum):
    STARTING = "starting"
    SCANNING = "scanning"
    RUNNING = "running"
    DEGRADED = "degraded"
    PORT_LOST = "port_lost"
    STOPPING = "stopping"


@dataclass
class DaemonOptions:
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
        self.keys = Keys(options.robot)
        self.tick_s = options.tick_ms / 1000.0
        self.status_period = 1.0 / float(dcfg.get("status_hz", 10.0))
        self.backoff_min = float(dcfg.get("reopen_backoff_min", 0.1))
        self.backoff_max = float(dcfg.get("reopen_backoff_max", 5.0))
        self.realtime_priority = check_priority(
            dcfg.get("realtime_priority", 0), "daemon.realtime_priority"
        )
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
        self.tick = 0
        self.bus_errors = 0
        self.frame: JointFrame | None = None
        self._sampled_at = time.time()
        self._stop = threading.Event()
        self._wake = threading.Event()  # a command arrived (the port-lost wait ends at once)
        self._safe_stop = threading.Event()
        self._status_dirty = True
        self._last_start: float | None = None  # start of the previous tick, for its real dt
        self._bus_down = False  # port lost: commands that need the bus are refused
        self._hold_on_return = False  # the first tick after the port is back holds the pose
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
        if new is not None:
            self._emit("lease", f"lease acquired by {new.name!r}", holder=new.to_dict())
        else:
            who = old.name if old else "?"
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

    def _set_state(self, state: DaemonState) -> None:
        if state != self.state:
            log.info("daemon state: %s → %s", self.state, state)
            self.state = state
            self._status_dirty = True
            if self.pub is not None:
                self.pub.event("state", f"daemon {state}", state=str(state))

    # -- lifecycle ---------------------------------------------------------------------------
    def start_network(self) -> None:
        zcfg = self.settings.get("zenoh", {})
        conf = server_config(
            self.options.listen,
            int(zcfg.get("link_lease_ms", 3000)),
            max_message_bytes=int(zcfg.get("max_message_bytes", MAX_MESSAGE_BYTES)),
            mode=str(zcfg.get("mode", "peer")),
        )
        if self.options.router:
            join_router(conf, self.options.router, self.options.connect)
            if self.options.credentials is not None:
                self.options.credentials.apply(conf)
        elif self.options.connect:
            conf.insert_json5("connect/endpoints", json.dumps(self.options.connect))
        if self.options.security is not None:
            self.options.security.apply(conf)
        try:
            self.session = zenoh.open(conf)
        except zenoh.ZError as exc:
            if self.options.router and "connect" in str(exc).lower():
                wait = ROUTER_CONNECT_TIMEOUT_MS / 1000
                raise ListenError(
                    f"cannot reach the router at {self.options.router}: nothing answered within "
                    f"{wait:g} s; start it first (`darwin router --listen ENDPOINT`) or fix "
                    "--router"
                ) from None
            raise ListenError(
                f"cannot listen on {', '.join(self.options.listen)}: {_zenoh_reason(exc)}; is "
                "another daemon or `darwin up` using it? Stop it, or pass --listen "
                "tcp/127.0.0.1:0 for any free port"
            ) from None
        finally:
            if self.options.security is not None:
                # Zenoh read the plaintext dictionary while opening: it need not stay on disk.
                self.options.security.close()
        self.pub = Publishers(self.session, self.keys)
        for kind, message, data in self._early_events:
            self.pub.event(kind, message, **data)
        self._early_events.clear()
        self.arbiter = Arbiter(self.session, self.keys, self.lease, limits=self.arbiter_limits)
        self.arbiter.gate = self._outage_gate
        self.arbiter.on_wakeup = self._wake.set
        self._alive = self.session.liveliness().declare_token(self.keys.alive)
        self._alive_version = self.session.liveliness().declare_token(
            self.keys.alive_version(fmt(self.protocol), package_version())
        )
        self._roles = serve_roles(self.session, self.keys)
        self.policy_link = link_policy(self.session, self.keys, self.manager, self.pub, self)
        if self.options.camera != "none":
            from robot_daemon.camera import CameraThread

            self.camera = CameraThread.from_settings(
                self.session, self.keys, self.options.camera, self.settings
            )

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

    def _update_state(self) -> None:
        st = self.bus.state
        healthy = self.bus.cm730_online and all(st.online[j] for j in self.robot.ids)
        self._set_state(DaemonState.RUNNING if healthy else DaemonState.DEGRADED)

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()

    def close(self) -> None:
        """Halt the motion and hold the pose, then let go of everything (the bus last)."""
        self._set_state(DaemonState.STOPPING)
        self._halt_and_hold()
        self._publish_status(time.monotonic())
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
        while not self._stop.is_set():
            if not self.bus.is_open:
                self._reconnect()
                continue
            try:
                self._loop()
            except PortError as exc:
                if self._stop.is_set():
                    return  # shutting down: the emulator may simply have stopped first
                self._port_lost(exc)
            except Exception as exc:
                # A failure nobody foresaw must not end the daemon: report it, start the bus
                # over as if the port had gone.
                log.exception("the motion loop failed")
                if self._stop.is_set():
                    return
                self._port_lost(exc)

    def _loop(self) -> None:
        next_deadline = time.monotonic()
        self._last_start = None
        self.stats.reset_period()
        while not self._stop.is_set():
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
            self._stop.wait(max(0.0, next_deadline - time.monotonic()))

    def _one_tick(self, start: float) -> float:
        """One tick; returns the time spent on the bus."""
        bus_t0 = time.monotonic()
        self.bus.read_sensors()
        check_dxl_power(self.bus)  # raises DxlPowerLostError: halt, power on, scan, hold
        bus_read = time.monotonic() - bus_t0
        # Stamp the data when it was sampled, not when the tick got round to publishing it, so
        # stamp differences are the sampling interval whatever the tick's work took.
        self._sampled_at = time.time()
        self.tick += 1
        # Motion time is the time that passed (bounded), so late ticks do not slow the gait.
        last, self._last_start = self._last_start, start
        dt = self.tick_s if last is None else min(start - last, MAX_DT_TICKS * self.tick_s)
        frame = self.bus.frame(self.tick, start, dt)
        self.frame = frame
        if self._safe_stop.is_set():
            self._safe_stop.clear()
            self.manager.stop_all()
        if self._hold_on_return:
            # The port is back: whatever goals the servos kept, hold the present pose.
            self._hold_on_return = False
            self.manager.hold_present(frame)
        assert self.arbiter is not None
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
        self._publish(frame, targets, start)
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
        )

    # -- publication -------------------------------------------------------------------------
    def _publish(self, frame: JointFrame, targets: Targets, now: float) -> None:
        assert self.pub is not None
        for kind, message, data in self.manager.drain_events():
            self.pub.event(kind, message, **data)
        # Built only for someone: a message nobody subscribes to costs the tick for nothing.
        if self.pub.wanted("joints"):
            self.pub.post("joints", self._joints_message(frame))
        if self.pub.wanted("imu"):
            self.pub.post("imu", self._imu_message(frame))
        self._update_state()
        # Every tick (a lock and a clock read): a silent holder's lease ends within one tick of
        # heartbeat_timeout after its last renewal, so a cut link stops the robot within it.
        if self.lease.expire():
            self._status_dirty = True
        if self._status_dirty or now - self._last_status >= self.status_period:
            # The battery and heat policy at the status rate (10 Hz), not per tick.
            st = self.bus.state
            self.guard.check(self.bus.cm730_status()["voltage"], st.temperature, st.online, now)
            self._publish_status(now)

    def _joints_message(self, frame: JointFrame) -> Joints:
        # Whole arrays, indexed once by the joint IDs: this runs every tick.
        st = self.bus.state
        ids = self.robot.ids
        idx = list(ids)
        pos = frame.position[idx]
        return Joints(
            id=idx,
            name=list(self.robot.names),
            position=pos.tolist(),
            position_deg=np.degrees(pos).tolist(),
            goal=self.bus.calibration.positions(st.goal)[idx].tolist(),
            velocity=frame.velocity[idx].tolist(),
            load=frame.load[idx].tolist(),
            temperature=st.temperature[idx].astype(float).tolist(),
            voltage=st.voltage[idx].astype(float).tolist(),
            torque_enabled=st.torque[idx].astype(bool).tolist(),
            online=st.online[idx].astype(bool).tolist(),
            alarm=st.alarm[idx].astype(int).tolist(),
            stamp=self._sampled_at,
            tick=self.tick,
        )

    def _imu_message(self, frame: JointFrame) -> Imu:
        # The fall monitor (a motion module) classified this frame in manager.step.
        fall = self.fall.direction if self.fall is not None else "none"
        return Imu(
            gyro=[float(v) for v in frame.gyro],
            accel=[float(v) for v in frame.accel],
            gyro_raw=[int(v) for v in frame.gyro_raw],
            accel_raw=[int(v) for v in frame.accel_raw],
            fall=fall,
            stamp=self._sampled_at,
            tick=self.tick,
        )

    def status_message(self) -> Status:
        cm = self.bus.cm730_status()
        st = self.bus.state
        alarms = [{"id": j, "bits": int(st.alarm[j])} for j in self.robot.ids if st.alarm[j]]
        extra: dict[str, Any] = {}
        if self.camera is not None:
            extra["camera"] = self.camera.status()
        else:
            extra["camera"] = {"source": "none", "captured": 0, "subscribed": False}
        return Status(
            state=str(self.state),
            robot=self.options.robot,
            lease=self.lease.status(),
            motion=self.manager.status(),
            leds=cm["leds"],
            buttons=cm["buttons"],
            bus={
                **self.bus.status(),
                "bus_errors": self.bus_errors,
                "arbiter": self.arbiter.counts if self.arbiter else {},
            },
            loop={
                **self.stats.summary(),
                "scheduling": self.scheduling,
                "events_dropped": self.pub.dropped_events if self.pub is not None else 0,
            },
            voltage=cm["voltage"],
            alarms=alarms,
            network=self.network_info(),
            version=package_version(),
            power=self.guard.status()[0],
            heat=self.guard.status()[1],
            protocol=list(self.protocol),
            **extra,
        )

    def network_info(self) -> NetworkInfo:
        router = self.options.router
        listen = list(self.options.listen)
        return NetworkInfo(
            endpoint=router or (listen[0] if listen else ""), router=router, listen=listen
        )

    def _publish_status(self, now: float) -> None:
        if self.pub is None:
            return
        self._status_dirty = False
        self._last_status = now
        self.pub.post("status", self.status_message())

    # -- port loss ---------------------------------------------------------------------------
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


def _zenoh_reason(exc: Exception) -> str:
    """Zenoh's error without its Rust source paths."""
    text = str(exc).strip()
    if "already in use" in text.lower():
        return "the address is already in use"
    text = text.splitlines()[0] if text else type(exc).__name__
    return text.split(" at /", 1)[0][:160]
