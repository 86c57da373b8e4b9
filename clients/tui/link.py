"""The TUI's connection to one robot: a :class:`clients.robot.Robot`, kept alive and re-made.

A connector thread opens the Zenoh session (retrying while the endpoint is unreachable) and
watches the daemon's liveliness token; Zenoh itself re-links a client session when the daemon
comes back. Robot callbacks run on Zenoh threads: they put samples in the :class:`Inbox` and
wake the app with at most one queued message (clients/tui/messages.py says why).

Commands go through one queue and one thread so they reach the arbiter in the order the user
gave them (walk start before walk stop); ``halt`` skips the queue.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import queue
import threading
from collections import deque
from dataclasses import dataclass
from typing import Any

import zenoh
from textual.app import App
from textual.message import Message

from clients.robot import Robot, Subscription
from clients.tui.messages import (
    LinkChanged,
    LinkInfo,
    LinkState,
    TelemetryReady,
    VersionNotice,
)
from schemas import messages as wire
from schemas.errors import ClientError, DarwinError, IncompatibleProtocolError
from schemas.roles import Role
from schemas.session import Credentials, resolve

log = logging.getLogger(__name__)
RETRY_S = 2.0
# How long ``close`` waits for the link's threads still inside a Zenoh call (a command ends by
# its timeout, 3 s by default, or at once when the session closes; a session being opened by
# its connect timeout), as clients/lease_keeper.py's drop does.
DRAIN_S = 5.0
# Samples kept for an app that is not taking them: > 15 s of joints and IMU at 125 Hz; older
# ones go first (the plots' oldest points). Events are never dropped; of camera frames only the
# newest is kept.
INBOX_SAMPLES = 4000


def _drain(items: deque[Any]) -> list[Any]:
    """Everything in ``items``, oldest first; appends from other threads meanwhile may stay."""
    out = []
    for _ in range(len(items)):
        out.append(items.popleft())
    return out


class Inbox:
    """Samples from Zenoh threads for the app's thread, with one wake-up message at most."""

    def __init__(self, app: App[Any]) -> None:
        self.app = app
        self._samples: deque[tuple[str, Any]] = deque(maxlen=INBOX_SAMPLES)
        self._events: deque[Any] = deque()
        self._frame: Any = None
        self._woken = threading.Event()

    def put(self, topic: str, sample: Any) -> None:
        if topic == "events":
            self._events.append(sample)
        elif topic == "camera":
            self._frame = sample
        else:
            self._samples.append((topic, sample))
        if not self._woken.is_set():
            self._woken.set()
            self.app.post_message(TelemetryReady())

    def take(self) -> list[tuple[str, Any]]:
        """Everything put since the last take, each stream oldest first (the app's thread)."""
        # Cleared before taking: a put racing with this take wakes the app once more.
        self._woken.clear()
        out: list[tuple[str, Any]] = [("events", e) for e in _drain(self._events)]
        out += _drain(self._samples)
        frame, self._frame = self._frame, None
        if frame is not None:
            out.append(("camera", frame))
        return out


@dataclass
class CommandDone(Message, bubble=False):
    """The outcome of one command: ``applied`` on success, ``error`` otherwise."""

    verb: str
    tag: str
    applied: dict[str, Any]
    error: str = ""
    quiet: bool = False


@dataclass
class _Command:
    """A command the UI asked for, waiting for the command thread."""

    verb: str
    fields: dict[str, Any]
    tag: str = ""
    quiet: bool = False


class Link:
    def __init__(
        self, app: App[Any], name: str = "tui", credentials: Credentials | None = None
    ) -> None:
        self.app = app
        self.name = name
        self.credentials = credentials  # None: the environment's or the client file's
        # What the robot's access control lets us do (None: unknown, everything is offered).
        self.role: Role | None = None
        self.robot: Robot | None = None
        self.info = LinkInfo(LinkState.IDLE, "", "")
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._busy = 0  # the link's threads not yet ended: the connectors, commands, halts
        self._idle = threading.Condition(self._lock)  # notified when one ends
        self._ours = threading.local()  # .here in a thread of the link's own
        self._connector: threading.Thread | None = None
        self._commands: queue.Queue[_Command | None] = queue.Queue()
        self._runner = self._spawn("tui-commands", self._run_commands)
        self._camera: Subscription | None = None
        self._liveliness: Any = None
        self.inbox = Inbox(app)

    @property
    def client_id(self) -> str:
        return self.robot.client_id if self.robot else ""

    # -- connection ------------------------------------------------------------------------------
    def connect(self, endpoint: str, robot: str) -> None:
        """(Re)connect to ``robot`` at ``endpoint``; returns at once, the state is posted."""
        # Raises ValueError on a bad value (endpoint, name, credentials).
        target = resolve(endpoint or None, robot or None, self.credentials)
        self.disconnect()
        self._stop = threading.Event()
        self._set(LinkState.CONNECTING, target.endpoint, target.robot)
        self._connector = self._spawn(
            "tui-connect", self._connect_loop, target.endpoint, target.robot, self._stop
        )

    def _spawn(self, name: str, target: Any, *args: Any) -> threading.Thread:
        """A daemon thread of the link's, counted until it ends (``close`` waits for it)."""
        with self._lock:
            self._busy += 1  # before it starts: a close right after must wait for it

        def run() -> None:
            self._ours.here = True
            try:
                target(*args)
            finally:
                with self._idle:
                    self._busy -= 1
                    self._idle.notify_all()

        thread = threading.Thread(target=run, name=name, daemon=True)
        thread.start()
        return thread

    def _connect_loop(self, endpoint: str, robot_name: str, stop: threading.Event) -> None:
        while not stop.is_set():
            try:
                robot = Robot(
                    endpoint, robot_name, name=self.name, timeout=3.0, credentials=self.credentials
                )
            except ClientError as exc:
                self._set(LinkState.UNREACHABLE, endpoint, robot_name, str(exc))
                stop.wait(RETRY_S)
                continue
            with self._lock:
                if stop.is_set():
                    robot.close()
                    return
                self.robot = robot
            self._attach(robot, stop)
            return

    def _telemetry(self, topic: str, msg: wire.Message) -> None:
        self.inbox.put(topic, msg)

    def _attach(self, robot: Robot, stop: threading.Event) -> None:
        for topic in ("joints", "imu", "status", "events", "vision"):  # camera: watch_camera
            robot.subscribe(topic, functools.partial(self._telemetry, topic))
        ep, name = robot.target.endpoint, robot.target.robot
        try:
            self.role = robot.role  # asked here, off the UI thread, before CONNECTED is posted
        except Exception:  # a session closing under us: the role stays unknown
            self.role = None
        alive = robot.alive(1.0)
        try:
            # Its first status says its versions: another major is refused before CONNECTED
            # shows, when that status comes in time.
            if alive:
                robot.check_protocol(3.0)
        except IncompatibleProtocolError as exc:
            self._set(LinkState.UNREACHABLE, ep, name, str(exc))
            return
        if stop.is_set():  # disconnected meanwhile: the robot is closed, nothing to listen to
            return
        self._set(LinkState.CONNECTED if alive else LinkState.NO_DAEMON, ep, name)

        def on_versions(warning: str | None, error: IncompatibleProtocolError | None) -> None:
            # Whenever the announcement comes (a loaded machine, a daemon upgraded under us).
            if error is not None:
                self._set(LinkState.UNREACHABLE, ep, name, str(error))
            elif warning:
                self.app.post_message(VersionNotice(warning))

        robot.protocol.listen(on_versions)

        def on_token(sample: zenoh.Sample) -> None:
            up = sample.kind == zenoh.SampleKind.PUT
            self._set(LinkState.CONNECTED if up else LinkState.NO_DAEMON, ep, name)

        self._liveliness = robot.session.liveliness().declare_subscriber(
            robot.keys.alive, on_token, history=True
        )

    def _set(self, state: LinkState, endpoint: str, robot: str, detail: str = "") -> None:
        self.info = LinkInfo(state, endpoint, robot, detail)
        self.app.post_message(LinkChanged(self.info))

    def disconnect(self) -> None:
        self._stop.set()
        with self._lock:
            robot, self.robot = self.robot, None
            self._camera = None
            liveliness, self._liveliness = self._liveliness, None
        if liveliness is not None:
            with contextlib.suppress(Exception):
                liveliness.undeclare()
        if robot is not None:
            robot.close()

    def close(self) -> None:
        """Disconnect and end the link's threads, waiting for them (``DRAIN_S`` at most)."""
        self.disconnect()
        self._commands.put(None)
        # A thread of the link's still inside a Zenoh call (a command's query, a session
        # being opened, the connect's first queries) when the TUI exits would come back into
        # a finalizing Python and be ended by pthread_exit through Zenoh's Rust frames, which
        # aborts the process ("FATAL: exception not rethrown", exit -6), as a Robot's lease
        # renewals did (clients/lease_keeper.py). The robot is closed by now, so a call in
        # flight ends at once. Not from a thread of the link's own, which would wait for itself.
        if not getattr(self._ours, "here", False):
            with self._idle:
                self._idle.wait_for(lambda: self._busy == 0, timeout=DRAIN_S)

    # -- camera: subscribed only while someone looks at it ----------------------------------------
    def watch_camera(self, on: bool) -> None:
        robot = self.robot
        if on and self._camera is None and robot is not None:
            self._camera = robot.subscribe("camera", self._on_frame)
        elif not on and self._camera is not None:
            sub, self._camera = self._camera, None
            with contextlib.suppress(Exception):
                sub.close()

    @property
    def watching_camera(self) -> bool:
        return self._camera is not None

    def _on_frame(self, frame: Any) -> None:
        self.inbox.put("camera", frame)

    # -- commands --------------------------------------------------------------------------------
    def send(self, verb: str, *, tag: str = "", quiet: bool = False, **fields: Any) -> None:
        """Queue a command; its outcome is posted as :class:`CommandDone`."""
        self._commands.put(_Command(verb, fields, tag, quiet))

    def halt(self) -> None:
        """Halt now, from a thread of its own: it never waits behind queued commands."""
        self._spawn("tui-halt", self._execute, _Command("halt", {}, "halt"))

    def _run_commands(self) -> None:
        while True:
            cmd = self._commands.get()
            if cmd is None:
                return
            self._execute(cmd)

    def _execute(self, cmd: _Command) -> None:
        robot = self.robot
        if robot is None:
            error = "not connected to a robot yet"
            self.app.post_message(CommandDone(cmd.verb, cmd.tag, {}, error))
            return
        try:
            applied = robot.command(cmd.verb, **cmd.fields)
        except DarwinError as exc:
            self.app.post_message(CommandDone(cmd.verb, cmd.tag, {}, str(exc)))
            return
        except Exception as exc:  # a Zenoh error from a closing session: report, never crash
            log.debug("command %s failed", cmd.verb, exc_info=True)
            self.app.post_message(CommandDone(cmd.verb, cmd.tag, {}, f"{cmd.verb}: {exc}"))
            return
        self.app.post_message(CommandDone(cmd.verb, cmd.tag, applied, quiet=cmd.quiet))
