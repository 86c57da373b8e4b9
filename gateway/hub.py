"""One Zenoh subscription per stream, shared by every legacy connection.

The hub is a :class:`clients.robot.Robot` on the gateway's one Zenoh session: it follows status
and events always (the orchestrate/playball replies need them), joints and IMU only while at
least one legacy client is connected, and the camera only while at least one client monitors
it, since the daemon captures frames only while someone subscribes. A gateway nobody uses
decodes no 125 Hz stream (that cost 5 % of a core here, and the daemon's building of them for it
3 % more: more on the robot's Atom, where the gateway runs beside the loop), and the daemon,
seeing nobody watch joints or IMU, builds neither. Latest-value streams are read when a client's
period comes due, so 125 Hz publications never wake the event loop; events are handed to it
with ``call_soon_threadsafe`` (Zenoh callbacks run in Zenoh's threads).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable
from typing import Any

from clients.robot import Robot, Subscription
from gateway.monitor import (
    CameraImage,
    Snapshot,
    accelerometer_from_imu,
    camera_from_frame,
    gyroscope_from_imu,
    motors_from_joints,
)
from schemas.messages import CameraFrame, Event, Imu, Joints, Message, Status

log = logging.getLogger(__name__)

EventListener = Callable[[Event], None]
StatusListener = Callable[[Status], None]


class HubRobot(Robot):
    """The gateway's :class:`Robot`: status and events from the start; joints and IMU are the
    hub's to follow while clients are connected (:meth:`Hub.join`)."""

    followed = ("status", "events")


class Hub:
    def __init__(self, robot: Robot, loop: asyncio.AbstractEventLoop) -> None:
        self.robot = robot
        self._loop = loop
        self._clients = 0
        self._telemetry: list[Subscription] = []
        # The newest of each while clients are connected (None: none since the first joined).
        self._joints: Joints | None = None
        self._imu: Imu | None = None
        self._camera_users = 0
        self._camera_sub: Subscription | None = None
        self._camera_frame: CameraFrame | None = None
        self._event_listeners: set[EventListener] = set()
        self._status_listeners: set[StatusListener] = set()
        # Conversions are cached by the identity of the message they came from, so fifty
        # clients on one sample cost one conversion.
        self._cache: dict[str, tuple[object, Any]] = {}
        self._subs = [
            robot.subscribe("events", self._from_zenoh),
            robot.subscribe("status", self._from_zenoh),
        ]

    def close(self) -> None:
        for sub in self._subs + self._telemetry:
            with contextlib.suppress(Exception):
                sub.close()
        if self._camera_sub is not None:
            with contextlib.suppress(Exception):
                self._camera_sub.close()
            self._camera_sub = None

    # -- latest values -------------------------------------------------------------------------
    def _converted(self, name: str, source: object, convert: Callable[[Any], Any]) -> Any:
        if source is None:
            return None
        cached = self._cache.get(name)
        if cached is not None and cached[0] is source:
            return cached[1]
        value = convert(source)
        self._cache[name] = (source, value)
        return value

    def snapshot(self) -> Snapshot:
        joints, imu = self._joints, self._imu
        return Snapshot(
            motors=self._converted("motors", joints, motors_from_joints),
            accelerometer=self._converted("accel", imu, accelerometer_from_imu),
            gyroscope=self._converted("gyro", imu, gyroscope_from_imu),
            camera=self._camera_image(),
        )

    # -- joints and IMU, only while clients are connected -----------------------------------
    def join(self) -> None:
        """A legacy client connected: the first one starts the joints and IMU streams."""
        self._clients += 1
        if not self._telemetry:
            log.info("first client connected: following joints and IMU")
            self._telemetry = [
                self.robot.subscribe("joints", self._on_telemetry),
                self.robot.subscribe("imu", self._on_telemetry),
            ]

    def leave(self) -> None:
        """A legacy client disconnected: the last one stops them (a later client never sees
        values older than its connection)."""
        self._clients = max(0, self._clients - 1)
        if self._clients == 0 and self._telemetry:
            log.info("no client connected: no longer following joints and IMU")
            for sub in self._telemetry:
                with contextlib.suppress(Exception):
                    sub.close()
            self._telemetry = []
            self._joints = self._imu = None

    def _on_telemetry(self, msg: Message) -> None:
        # A Zenoh thread: swapping one reference is atomic, readers take whichever is newest.
        if isinstance(msg, Joints):
            self._joints = msg
        elif isinstance(msg, Imu):
            self._imu = msg

    def _camera_image(self) -> CameraImage | None:
        return self._converted("camera", self._camera_frame, camera_from_frame)

    # -- the camera, only while watched ------------------------------------------------------
    def watch_camera(self) -> None:
        self._camera_users += 1
        if self._camera_sub is None:
            log.info("first client monitors the camera: subscribing")
            self._camera_sub = self.robot.subscribe("camera", self._on_camera)

    def unwatch_camera(self) -> None:
        self._camera_users = max(0, self._camera_users - 1)
        if self._camera_users == 0 and self._camera_sub is not None:
            log.info("no client monitors the camera: unsubscribing")
            self._camera_sub.close()
            self._camera_sub = None
            self._camera_frame = None

    def _on_camera(self, msg: Message) -> None:
        # A Zenoh thread: swapping one reference is atomic, readers take whichever is newest.
        if isinstance(msg, CameraFrame):
            self._camera_frame = msg

    # -- events and status -------------------------------------------------------------------
    def add_event_listener(self, fn: EventListener) -> None:
        self._event_listeners.add(fn)

    def add_status_listener(self, fn: StatusListener) -> None:
        self._status_listeners.add(fn)

    def _from_zenoh(self, msg: Message) -> None:
        with contextlib.suppress(RuntimeError):  # the loop is closing: nobody to tell
            self._loop.call_soon_threadsafe(self._dispatch, msg)

    def _dispatch(self, msg: Message) -> None:
        listeners: list[Callable[[Any], None]]
        if isinstance(msg, Event):
            listeners = list(self._event_listeners)
        elif isinstance(msg, Status):
            listeners = list(self._status_listeners)
        else:
            return
        for fn in listeners:
            try:
                fn(msg)
            except Exception:
                log.exception("monitor listener failed on %s", type(msg).__name__)
