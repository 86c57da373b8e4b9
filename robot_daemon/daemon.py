"""The robot daemon: the 8 ms motion loop, publication on the key space, the arbiter.

One motion thread owns the bus. Each tick, at an absolute deadline: bulk-read the sensors,
apply queued commands, run the motion modules, sync-write the goals, hand the messages to the
publisher thread. A lost port is reopened with back-off while ``status.state`` says so.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

import zenoh

from config.loader import RobotConfig
from robot_daemon.arbiter.core import Arbiter
from robot_daemon.arbiter.lease import Holder, Lease
from robot_daemon.arbiter.registry import MotionContext
from robot_daemon.bus.robot_bus import RobotBus
from robot_daemon.loop_stats import LoopStats
from robot_daemon.motion.interface import JointFrame, Targets
from robot_daemon.motion.setup import build_manager
from robot_daemon.publishers import Publishers
from robot_daemon.realtime import check_priority, current_policy, enter_realtime
from schemas.errors import BusError, PortError
from schemas.keys import Keys
from schemas.messages import Imu, Joints, Status
from schemas.session import server_config

log = logging.getLogger(__name__)


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
    extras: dict[str, Any] = field(default_factory=dict)


class FallDetector:
    """The framework's rule: mean of the last N front/back accelerometer counts."""

    def __init__(self, settings: dict[str, Any]) -> None:
        imu = settings.get("imu", {})
        self.forward_below = float(imu.get("fall_forward_below", 390))
        self.backward_above = float(imu.get("fall_backward_above", 580))
        self.samples: deque[int] = deque(maxlen=int(imu.get("fall_window", 30)))

    def update(self, accel_front_back_raw: int) -> str:
        self.samples.append(accel_front_back_raw)
        if len(self.samples) < self.samples.maxlen:  # type: ignore[operator]
            return "none"
        mean = sum(self.samples) / len(self.samples)
        if mean < self.forward_below:
            return "forward"
        if mean > self.backward_above:
            return "backward"
        return "none"


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
        self.stats = LoopStats(self.tick_s)
        self.manager = build_manager(robot, settings)
        self.bus = RobotBus(options.port, robot, settings, self._emit)
        self.fall = FallDetector(settings)
        self.tick = 0
        self.bus_errors = 0
        self.frame: JointFrame | None = None
        self._sampled_at = time.time()
        self._stop = threading.Event()
        self._safe_stop = threading.Event()
        self._status_dirty = True
        self._fall_state = "none"
        self.camera: Any = None
        self.session: zenoh.Session | None = None
        self.pub: Publishers | None = None
        self.arbiter: Arbiter | None = None
        self.lease = Lease(
            float(dcfg.get("lease", {}).get("idle_timeout", 60.0)), on_change=self._lease_changed
        )
        self._early_events: list[tuple[str, str, dict[str, Any]]] = []

    # -- events and lease --------------------------------------------------------------------
    def _emit(self, kind: str, message: str, **data: Any) -> None:
        if self.pub is None:
            self._early_events.append((kind, message, data))
        else:
            self.pub.event(kind, message, **data)
        if kind.startswith("servo_"):
            self._status_dirty = True

    def _lease_changed(self, old: Holder | None, new: Holder | None, reason: str) -> None:
        if new is not None:
            self._emit("lease", f"lease acquired by {new.name!r}", holder=new.to_dict())
        else:
            who = old.name if old else "?"
            self._emit("lease", f"lease of {who!r} ended: {reason}", holder=None, reason=reason)
            if reason != "released":
                # The controller vanished or went quiet: bring the robot to a safe stop.
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
        zcfg = self.settings.get("zenoh", {})
        conf = server_config(
            self.options.listen,
            int(zcfg.get("link_lease_ms", 3000)),
            str(zcfg.get("mode", "peer")),
        )
        if self.options.connect:
            conf.insert_json5("connect/endpoints", json.dumps(self.options.connect))
        self.session = zenoh.open(conf)
        self.pub = Publishers(self.session, self.keys)
        for kind, message, data in self._early_events:
            self.pub.event(kind, message, **data)
        self._early_events.clear()
        self.arbiter = Arbiter(self.session, self.keys, self.lease)
        self._alive = self.session.liveliness().declare_token(self.keys.alive)
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

    def close(self) -> None:
        self._set_state(DaemonState.STOPPING)
        self._publish_status(time.monotonic())
        if self.camera is not None:
            self.camera.close()
        if self.arbiter is not None:
            self.arbiter.close()
        with contextlib.suppress(Exception):
            self._alive.undeclare()
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
        bus_read = time.monotonic() - bus_t0
        # Stamp the data when it was sampled, not when the tick got round to publishing it, so
        # stamp differences are the sampling interval whatever the tick's work took.
        self._sampled_at = time.time()
        self.tick += 1
        frame = self.bus.frame(self.tick, start, self.tick_s)
        self.frame = frame
        if self._safe_stop.is_set():
            self._safe_stop.clear()
            self.manager.stop_all()
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
            extras={
                "allow_eeprom": self.options.allow_eeprom,
                "lease": self.lease,
                "daemon": self,
                **self.options.extras,
            },
        )

    # -- publication -------------------------------------------------------------------------
    def _publish(self, frame: JointFrame, targets: Targets, now: float) -> None:
        assert self.pub is not None
        for kind, message, data in self.manager.drain_events():
            self.pub.event(kind, message, **data)
        self.pub.post("joints", self._joints_message(frame))
        self.pub.post("imu", self._imu_message(frame))
        self._update_state()
        if self.tick % 25 == 0 and self.lease.expire():
            self._status_dirty = True
        if self._status_dirty or now - self._last_status >= self.status_period:
            self._publish_status(now)

    def _joints_message(self, frame: JointFrame) -> Joints:
        st = self.bus.state
        ids = list(self.robot.ids)
        pos = [float(frame.position[j]) for j in ids]
        return Joints(
            id=ids,
            name=list(self.robot.names),
            position=pos,
            position_deg=[math.degrees(p) for p in pos],
            goal=[self.bus.raw_to_joint(j, int(st.goal[j])) for j in ids],
            velocity=[float(frame.velocity[j]) for j in ids],
            load=[float(frame.load[j]) for j in ids],
            temperature=[float(st.temperature[j]) for j in ids],
            voltage=[float(st.voltage[j]) for j in ids],
            torque_enabled=[bool(st.torque[j]) for j in ids],
            online=[bool(st.online[j]) for j in ids],
            alarm=[int(st.alarm[j]) for j in ids],
            stamp=self._sampled_at,
            tick=self.tick,
        )

    def _imu_message(self, frame: JointFrame) -> Imu:
        fall = self.fall.update(int(frame.accel_raw[0]))
        if fall != self._fall_state:
            self._fall_state = fall
            if fall != "none":
                self._emit("fall", f"the robot has fallen {fall}", direction=fall)
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
            loop={**self.stats.summary(), "scheduling": self.scheduling},
            voltage=cm["voltage"],
            alarms=alarms,
            **extra,
        )

    def _publish_status(self, now: float) -> None:
        if self.pub is None:
            return
        self._status_dirty = False
        self._last_status = now
        self.pub.post("status", self.status_message())

    # -- port loss ---------------------------------------------------------------------------
    def _port_lost(self, exc: Exception) -> None:
        log.warning("serial port lost: %s", exc)
        self._emit(
            "fault", f"serial port lost: {exc}; reopening with back-off", port=self.bus.port_name
        )
        self.bus.close()
        self.bus.counters.port_reopens += 1
        self._set_state(DaemonState.PORT_LOST)
        self._backoff = self.backoff_min

    def _reconnect(self) -> None:
        """Try to reopen the port; while it fails, keep answering commands and status."""
        backoff = getattr(self, "_backoff", self.backoff_min)
        try:
            self.connect_bus()
            self._emit("port", f"serial port {self.bus.port_name} is back")
            return
        except BusError as exc:
            log.info("reopening %s failed: %s", self.bus.port_name, exc)
            self.bus.close()
            self._set_state(DaemonState.PORT_LOST)
        deadline = time.monotonic() + backoff
        self._backoff = min(backoff * 2, self.backoff_max)
        while not self._stop.is_set() and time.monotonic() < deadline:
            if self.arbiter is not None:
                self.arbiter.apply_pending(self._context(self.frame))
            self._publish_status(time.monotonic())
            self._stop.wait(min(self.status_period, max(0.0, deadline - time.monotonic())))
