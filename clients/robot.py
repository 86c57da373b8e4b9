"""The `Robot` client: connect, latest state, subscribe, commands, the control lease.

    >>> from clients import Robot
    >>> with Robot() as robot:                 # DARWIN_ENDPOINT / DARWIN_ROBOT or local defaults
    ...     state = robot.wait_ready()         # the first messages have arrived
    ...     print(state.joints.position)
    ...     with robot.control("my notebook"):
    ...         robot.joint("head_pan", 0.3)

This module is the watching side (state, subscriptions, waiting, notebook tables and images);
the commands and the control lease are :class:`clients.commander.Commander`, which ``Robot``
extends and which is importable from here too.

A script that forgets ``close()`` still exits: every client still open is closed when the
interpreter ends (:mod:`clients.commander`).
"""

from __future__ import annotations

import contextlib
import functools
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import zenoh

from clients.arrivals import Arrivals
from clients.commander import Commander
from clients.protocol_watch import ProtocolWatch
from clients.teach import TeachMixin
from schemas.errors import CommandTimeoutError, ProtocolError
from schemas.keys import Keys
from schemas.messages import (
    BallDetection,
    CameraFrame,
    Event,
    Imu,
    Joints,
    M,
    Message,
    Status,
    World,
    decode,
)
from schemas.session import credentials as make_credentials
from schemas.session import resolve

if TYPE_CHECKING:
    from clients.fleet import RobotRecord

__all__ = ["ALWAYS", "TOPICS", "Commander", "Robot", "RobotState", "Subscription", "topic_key"]

log = logging.getLogger(__name__)

TOPICS: dict[str, type[Message]] = {
    "joints": Joints,
    "imu": Imu,
    "status": Status,
    "events": Event,
    "camera": CameraFrame,
    "vision": BallDetection,
    "world": World,
}

# Topics the client always follows (cheap, and what `state` shows); the camera is subscribed to
# only on demand because the daemon captures frames only while someone watches.
ALWAYS = ("joints", "imu", "status", "events")
# What ``wait_ready`` waits for: the topics ``state`` shows that every daemon publishes.
READY = ("joints", "imu", "status")
# Where a one-line error's fix is explained at length.
TROUBLESHOOTING = "docs/troubleshooting.md"


def topic_key(keys: Keys, topic: str) -> str:
    try:
        return keys.topics()[topic]
    except KeyError:
        raise ValueError(f"unknown topic {topic!r}; topics are {', '.join(TOPICS)}") from None


@dataclass
class RobotState:
    """The newest message of each stream a ``Robot`` has received (None: none yet)."""

    joints: Joints | None = None
    imu: Imu | None = None
    status: Status | None = None
    ball: BallDetection | None = None
    world: World | None = None

    def array(self, field: str = "position") -> Any:
        """The latest values as a numpy array: a joint column (``position``, ``load``…, in the
        order of ``joints.name``) or an IMU vector (``gyro``, ``accel``, ``*_raw``)."""
        import numpy as np

        for msg in (self.joints, self.imu):
            if msg is not None and field in getattr(msg, "__dataclass_fields__", {}):
                value = getattr(msg, field)
                if isinstance(value, list):
                    return np.asarray(value)
        raise ValueError(
            f"no array {field!r} in the state (joint columns: {', '.join(Joints.COLUMNS)}; "
            "IMU: gyro, accel, gyro_raw, accel_raw), or no message received yet"
        )


class Subscription:
    """A callback subscription; ``close()`` (or leaving a ``with`` block) ends it."""

    # The topic decides the message's type (TOPICS), so the callback takes that type.
    def __init__(self, robot: Robot, topic: str, callback: Callable[[Any], None]) -> None:
        self._robot = robot
        self.topic = topic
        self._callback = callback
        self._zsub: Any = None
        self.errors = 0  # exceptions the callback raised
        self.last_error: BaseException | None = None

    def _deliver(self, msg: Message) -> None:
        try:
            self._callback(msg)
        except Exception as exc:
            # Logged once with its traceback (a bug in the callback should be seen), then
            # counted: a callback failing on every message must not flood the log.
            self.errors += 1
            self.last_error = exc
            if self.errors == 1:
                log.exception(
                    "the %s subscription callback %r raised (further errors are counted in "
                    "Subscription.errors)",
                    self.topic,
                    self._callback,
                )

    def close(self) -> None:
        self._robot._unsubscribe(self)

    def __enter__(self) -> Subscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()



class Robot(Commander, TeachMixin):
    """Commands plus the robot's live state and subscriptions; action pages and teach mode
    (:mod:`clients.teach`)."""

    protocol: ProtocolWatch  # a Robot always watches (made as it opens)
    # The topics followed from the start and for as long as the Robot is open (``state``
    # shows them); any other topic only while someone subscribes or waits for it.
    followed: tuple[str, ...] = ALWAYS

    def _open_extra(self) -> None:
        self._lock = threading.Lock()
        self._state = RobotState()
        self._listeners: dict[str, list[Subscription]] = {}
        self._zsubs: dict[str, Any] = {}
        self._zkeys: dict[str, zenoh.KeyExpr] = {}  # each subscription's key
        # Samples that reached a subscription not theirs (another key or message type), ignored.
        self.strays = 0
        self._strays_seen: set[tuple[str, str, str]] = set()
        self._arrivals = Arrivals()
        self.protocol = ProtocolWatch(f"this client ({self.name})")
        for topic in self.followed:
            self._ensure_zsub(topic)

    def check_protocol(self, timeout: float = 3.0) -> str | None:
        """On connect: the daemon's versions against ours (``schemas/versions.py``); raises
        ``IncompatibleProtocolError`` on another protocol major, returns a minor skew's warning."""
        return self.protocol.wait(timeout)

    @staticmethod
    def discover(
        connect: str | None = None,
        timeout: float = 2.0,
        *,
        user: str | None = None,
        password: str | None = None,
    ) -> list[RobotRecord]:
        """Every live robot reachable at ``connect`` (a router's endpoint: the whole fleet;
        default ``DARWIN_ENDPOINT``, else the local one), as ``darwin list`` shows them: name,
        endpoint, state, lease holder, battery, alarms, loop rate. ``Robot(connect, name)``
        then reaches any of them through that same endpoint. ``user``/``password`` log in as
        ``Robot(user=…, password=…)`` does (else the environment's or the client file's)."""
        # Here, not at the top: a program driving one robot (the gateway, the TUI) need not load
        # the fleet's records to start.
        from clients.fleet import discover_at

        creds = make_credentials(user=user, password=password) if (user or password) else None
        return discover_at(resolve(connect).endpoint, timeout, creds=creds)

    def _close_extra(self) -> None:
        for sub in list(self._zsubs.values()):
            with contextlib.suppress(Exception):
                sub.undeclare()
        self._zsubs.clear()

    def __repr__(self) -> str:
        st = self._state.status
        lease = "none"
        if st is not None and st.lease:
            lease = "you" if st.lease.get("client") == self.client_id else st.lease.get("name", "?")
        n = len(self._state.joints.id) if self._state.joints else 0
        return f"<Robot {self.target.robot} at {self.target.endpoint}: {n} joints, lease: {lease}>"

    # -- state -------------------------------------------------------------------------------
    @property
    def state(self) -> RobotState:
        """A copy of the latest joints, IMU, status, ball and world messages. A field is
        ``None`` until its first message has arrived: ``wait_ready()`` waits for them."""
        with self._lock:
            return RobotState(**vars(self._state))

    def wait_ready(self, timeout: float = 5.0) -> RobotState:
        """Wait until the first joints, IMU and status messages have arrived and return the
        state. Right after ``Robot()`` nothing has arrived yet (``state.joints`` is ``None``);
        call this before reading ``state``. Raises ``CommandTimeoutError`` naming what did not
        arrive within ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        missing: list[str] = []
        for topic in READY:
            if self._arrivals.count(topic):
                continue
            try:
                self._arrivals.wait(topic, lambda m: True, max(0.0, deadline - time.monotonic()), 0)
            except CommandTimeoutError:
                missing.append(topic)
        if missing:
            raise CommandTimeoutError(
                f"no {', '.join(missing)} message from robot {self.target.robot!r} at "
                f"{self.target.endpoint} within {timeout:g} s: is its daemon running (`darwin "
                "up`, or `darwin list` for the robots there) and is the robot name right? "
                f"({TROUBLESHOOTING}#no-robot-found)"
            )
        return self.state

    def _on_sample(self, topic: str, sample: zenoh.Sample) -> None:
        payload = sample.payload.to_bytes()
        # A sample is this subscription's only on its key and of its topic's one message type.
        on_key = self._zkeys[topic].includes(sample.key_expr)
        try:
            msg = decode(payload)
        except ProtocolError:
            if topic == "status" and on_key:  # another protocol major: the watch says which
                self.protocol.observe(payload)
            return  # a foreign or newer publisher: ignore rather than crash the callback
        if not on_key or type(msg) is not TOPICS[topic]:
            self._stray(topic, str(sample.key_expr), msg)
            return
        if topic == "status":
            self.protocol.observe(vars(msg))
        with self._lock:
            # TOPICS gives each topic its one message type: the type says which state it is.
            if isinstance(msg, Joints):
                self._state.joints = msg
            elif isinstance(msg, Imu):
                self._state.imu = msg
            elif isinstance(msg, Status):
                self._state.status = msg
            elif isinstance(msg, BallDetection):
                self._state.ball = msg
            elif isinstance(msg, World):
                self._state.world = msg
            listeners = list(self._listeners.get(topic, ()))
        self._arrivals.add(topic, msg)
        for sub in listeners:
            sub._deliver(msg)

    def _stray(self, topic: str, key: str, msg: Message) -> None:
        # Zenoh delivered, twice in ~30 runs over a lossy link that reconnected, an IMU sample
        # to the status subscription (docs/links.md): acted on, it was taken for a daemon of
        # another protocol and a stale state. Never acted on; counted, and said once per kind.
        self.strays += 1
        what = (topic, key, msg.TYPE)
        if what not in self._strays_seen:
            self._strays_seen.add(what)
            log.warning(
                "a %r message on %s reached the %s subscription (%s): ignored (docs/links.md)",
                msg.TYPE,
                key,
                topic,
                self._zkeys[topic],
            )

    def _ensure_zsub(self, topic: str) -> None:
        if topic in self._zsubs:
            return
        key = topic_key(self.keys, topic)
        self._zkeys[topic] = zenoh.KeyExpr(key)
        self._zsubs[topic] = self.session.declare_subscriber(
            key, functools.partial(self._on_sample, topic)
        )

    def subscribe(self, topic: str, callback: Callable[[M], None]) -> Subscription:
        """Call ``callback(message)`` for every message on ``topic`` (a Zenoh thread calls it:
        keep it short, hand work to a queue)."""
        topic_key(self.keys, topic)
        sub = Subscription(self, topic, callback)
        with self._lock:
            self._listeners.setdefault(topic, []).append(sub)
        self._ensure_zsub(topic)
        return sub

    def _unsubscribe(self, sub: Subscription) -> None:
        with self._lock:
            subs = self._listeners.get(sub.topic, [])
            if sub in subs:
                subs.remove(sub)
            drop = sub.topic not in self.followed and not subs
        if drop and sub.topic in self._zsubs:
            # Undeclaring lets the daemon see nobody watches (the camera stops capturing).
            self._zsubs.pop(sub.topic).undeclare()

    def wait_for(
        self,
        topic: str,
        predicate: Callable[[Any], bool] = lambda m: True,
        timeout: float = 5.0,
        fresh: bool = True,
    ) -> Any:
        """Block until a message on ``topic`` satisfies ``predicate`` and return it. With
        ``fresh`` only messages arriving after the call count; otherwise the latest one may.
        Every message that arrives is tested, in order, not only the newest when this thread
        wakes: an event followed at once by another is not missed (:mod:`clients.arrivals`).
        Raises ``CommandTimeoutError`` if none does within ``timeout`` seconds."""
        self._ensure_zsub(topic)
        since = self._arrivals.count(topic)
        return self._arrivals.wait(topic, predicate, timeout, since if fresh else since - 1)

    # -- notebook helpers: tables and images ------------------------------------------------------
    def collect(
        self, topic: str, seconds: float = 5.0, max_messages: int | None = None
    ) -> list[Message]:
        """The messages of ``topic`` arriving in the next ``seconds`` (or until
        ``max_messages``), as message objects."""
        if seconds <= 0 and max_messages is None:
            raise ValueError(f"seconds must be > 0 (got {seconds}) unless max_messages is set")
        got: list[Message] = []
        enough = threading.Event()

        def keep(msg: Message) -> None:
            if max_messages is None or len(got) < max_messages:
                got.append(msg)
            if max_messages is not None and len(got) >= max_messages:
                enough.set()

        with self.subscribe(topic, keep):
            enough.wait(seconds if seconds > 0 else None)
        return list(got)

    def stream(
        self, topic: str = "joints", seconds: float = 5.0, max_messages: int | None = None
    ) -> Any:
        """Record ``topic`` for ``seconds`` into a pandas DataFrame, one row per message.

        Columns are flat: ``stamp``, ``tick``, then for joints ``<field>_<joint name>``
        (``position_r_knee``, ``load_l_hip_pitch``…), for vectors ``gyro_x``…, for maps
        ``<key>_<subkey>``. The index ``t`` is seconds since the first row's stamp. See
        :func:`clients.dataframes.to_frame`."""
        from clients.dataframes import to_frame

        return to_frame(topic, self.collect(topic, seconds, max_messages))

    def image(self, timeout: float = 3.0) -> Any:
        """One camera frame as an RGB ``numpy`` array (height × width × 3, uint8). The camera
        is subscribed only for this call, so the daemon captures only while someone looks."""
        frames = self.collect("camera", timeout, max_messages=1)
        if not frames:
            raise CommandTimeoutError(
                f"no camera frame from {self.target.robot} within {timeout:.1f} s: is the "
                "daemon's camera on (`darwin up --camera sim` or a real camera)?"
            )
        from clients.dataframes import decode_jpeg

        return decode_jpeg(frames[0].jpeg)  # type: ignore[attr-defined]  # a CameraFrame
