"""The `Robot` client: connect, latest state, subscribe, commands, the control lease.

    >>> from clients import Robot
    >>> with Robot() as robot:                 # DARWIN_ENDPOINT / DARWIN_ROBOT or local defaults
    ...     print(robot.state.joints.position)
    ...     with robot.control("my notebook"):
    ...         robot.joint("head_pan", 0.3)

Every command returns the arbiter's *applied* map or raises a :class:`schemas.errors.CommandError`
(``LeaseBusyError``, ``InvalidCommandError``…) or a :class:`schemas.errors.ClientError`.
"""

from __future__ import annotations

import contextlib
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, Self

import msgpack
import zenoh

from schemas.errors import (
    ClientError,
    CommandTimeoutError,
    ErrorCode,
    ProtocolError,
    RobotUnreachableError,
    command_error,
)
from schemas.keys import Keys
from schemas.messages import (
    BallDetection,
    CameraFrame,
    Event,
    Imu,
    Joints,
    Message,
    Status,
    World,
    command_payload,
    decode,
    decode_dict,
)
from schemas.session import Target, open_client, resolve

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


def topic_key(keys: Keys, topic: str) -> str:
    try:
        return keys.topics()[topic]
    except KeyError:
        raise ValueError(f"unknown topic {topic!r}; topics are {', '.join(TOPICS)}") from None


@dataclass
class RobotState:
    joints: Joints | None = None
    imu: Imu | None = None
    status: Status | None = None
    ball: BallDetection | None = None
    world: World | None = None


class Subscription:
    """A callback subscription; ``close()`` (or leaving a ``with`` block) ends it."""

    def __init__(self, robot: Robot, topic: str, callback: Callable[[Message], None]) -> None:
        self._robot = robot
        self.topic = topic
        self._callback = callback
        self._zsub: Any = None

    def close(self) -> None:
        self._robot._unsubscribe(self)

    def __enter__(self) -> Subscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Commander:
    """Commands and the lease, without any subscription: one per legacy connection in the
    gateway, many sharing one Zenoh session (pass ``session``)."""

    def __init__(
        self,
        endpoint: str | None = None,
        robot: str | None = None,
        *,
        name: str | None = None,
        client_id: str | None = None,
        timeout: float = 3.0,
        session: zenoh.Session | None = None,
    ) -> None:
        self.target: Target = resolve(endpoint, robot)
        self.keys = Keys(self.target.robot)
        self.client_id = client_id or uuid.uuid4().hex[:12]
        self.name = name or f"python-{self.client_id[:6]}"
        self.timeout = timeout
        self._own_session = session is None
        try:
            self.session = session or open_client(self.target.endpoint)
        except zenoh.ZError as exc:
            raise RobotUnreachableError(
                f"cannot open a Zenoh session to {self.target.endpoint}: {exc}. "
                "Is the daemon running there (`darwin up`)? Check --connect / DARWIN_ENDPOINT."
            ) from exc
        self._closed = False
        # The arbiter releases our lease (and safely stops the robot) when this token goes.
        self._token = self.session.liveliness().declare_token(self.keys.client(self.client_id))

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._close_extra()
        with contextlib.suppress(Exception):
            self._token.undeclare()
        if self._own_session:
            with contextlib.suppress(Exception):
                self.session.close()

    def _close_extra(self) -> None:
        pass

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def alive(self, timeout: float = 1.0) -> bool:
        """True when the daemon's liveliness token is visible."""
        replies = self.session.liveliness().get(self.keys.alive, timeout=timeout)
        return any(r.ok is not None for r in replies)

    # -- commands ----------------------------------------------------------------------------
    def command(self, verb: str, timeout: float | None = None, **fields: Any) -> dict[str, Any]:
        """Send one arbiter command; return its *applied* map or raise."""
        if self._closed:
            raise ClientError("this Robot is closed; create a new one")
        key = self.keys.cmd(verb)
        payload = command_payload(self.client_id, name=self.name, **fields)
        replies = list(self.session.get(key, payload=payload, timeout=timeout or self.timeout))
        if not replies:
            raise RobotUnreachableError(
                f"nobody answers {key} at {self.target.endpoint}: is the daemon for robot "
                f"{self.target.robot!r} running (`darwin up`), and is the robot name right?"
            )
        reply = replies[0]
        if reply.ok is not None:
            d = decode_dict(reply.ok.payload.to_bytes())
            return d.get("applied", {})
        raw = reply.err.payload.to_bytes()
        try:
            d = msgpack.unpackb(raw, raw=False)
        except Exception:
            d = None
        if not isinstance(d, dict):
            text = raw.decode("utf-8", "replace")
            if "timeout" in text.lower():
                raise CommandTimeoutError(f"{verb}: the daemon did not answer within the timeout")
            raise command_error(ErrorCode.INTERNAL, text, None, verb)
        raise command_error(d.get("code", "internal"), d.get("message", ""), d.get("field"), verb)

    def acquire(self) -> dict[str, Any]:
        return self.command("lease", op="acquire")

    def release(self) -> dict[str, Any]:
        return self.command("lease", op="release")

    @contextlib.contextmanager
    def control(self, name: str | None = None) -> Iterator[Self]:
        """Hold the control lease inside the block; released on exit, even on error."""
        if name:
            self.name = name
        self.acquire()
        try:
            yield self
        finally:
            with contextlib.suppress(Exception):
                self.release()

    def halt(self) -> dict[str, Any]:
        return self.command("halt")

    def config(self) -> dict[str, Any]:
        return self.command("config")

    def joint(
        self, joint: int | str, position: float, speed: float | None = None
    ) -> dict[str, Any]:
        fields: dict[str, Any] = {"position": position}
        fields["id" if isinstance(joint, int) else "name"] = joint
        if speed is not None:
            fields["speed"] = speed
        return self.command("joint", **fields)

    def pose(self, positions: dict[int | str, float], duration: float = 1.0) -> dict[str, Any]:
        return self.command(
            "pose", positions={str(k): v for k, v in positions.items()}, duration=duration
        )

    def torque(self, enable: bool, ids: list[int | str] | None = None) -> dict[str, Any]:
        fields: dict[str, Any] = {"enable": enable}
        if ids is not None:
            fields["ids"] = ids
        return self.command("torque", **fields)

    def led(
        self,
        head: tuple[int, int, int] | None = None,
        eye: tuple[int, int, int] | None = None,
        panel: int | None = None,
    ) -> dict[str, Any]:
        fields = {
            k: (list(v) if isinstance(v, tuple) else v)
            for k, v in (("head", head), ("eye", eye), ("panel", panel))
            if v is not None
        }
        return self.command("led", **fields)

    def registers(
        self, id: int, address: int, length: int | None = None, data: list[int] | None = None
    ) -> dict[str, Any]:
        if data is not None:
            return self.command("registers", id=id, address=address, data=list(data))
        return self.command("registers", id=id, address=address, length=length or 1)


class Robot(Commander):
    """Commands plus the robot's live state and subscriptions."""

    def __init__(
        self,
        endpoint: str | None = None,
        robot: str | None = None,
        *,
        name: str | None = None,
        client_id: str | None = None,
        timeout: float = 3.0,
        session: zenoh.Session | None = None,
    ) -> None:
        super().__init__(
            endpoint, robot, name=name, client_id=client_id, timeout=timeout, session=session
        )
        self._lock = threading.Lock()
        self._state = RobotState()
        self._listeners: dict[str, list[Subscription]] = {}
        self._zsubs: dict[str, Any] = {}
        self._conds = threading.Condition()
        self._seq: dict[str, int] = {}
        self._latest: dict[str, Message] = {}
        for topic in ALWAYS:
            self._ensure_zsub(topic)

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
        with self._lock:
            return RobotState(**vars(self._state))

    def _on_sample(self, topic: str, sample: zenoh.Sample) -> None:
        try:
            msg = decode(sample.payload.to_bytes(), TOPICS[topic])
        except ProtocolError:
            return  # a foreign or newer publisher: ignore rather than crash the callback
        with self._lock:
            if topic == "joints":
                self._state.joints = msg  # type: ignore[assignment]
            elif topic == "imu":
                self._state.imu = msg  # type: ignore[assignment]
            elif topic == "status":
                self._state.status = msg  # type: ignore[assignment]
            elif topic == "vision":
                self._state.ball = msg  # type: ignore[assignment]
            elif topic == "world":
                self._state.world = msg  # type: ignore[assignment]
            listeners = list(self._listeners.get(topic, ()))
        with self._conds:
            self._seq[topic] = self._seq.get(topic, 0) + 1
            self._latest[topic] = msg
            self._conds.notify_all()
        for sub in listeners:
            with contextlib.suppress(Exception):
                sub._callback(msg)

    def _ensure_zsub(self, topic: str) -> None:
        if topic in self._zsubs:
            return
        key = topic_key(self.keys, topic)
        self._zsubs[topic] = self.session.declare_subscriber(
            key, lambda s, t=topic: self._on_sample(t, s)
        )

    def subscribe(self, topic: str, callback: Callable[[Message], None]) -> Subscription:
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
            drop = sub.topic not in ALWAYS and not subs
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
        Raises ``CommandTimeoutError`` if none does within ``timeout`` seconds."""
        self._ensure_zsub(topic)
        deadline = time.monotonic() + timeout
        with self._conds:
            seen = self._seq.get(topic, 0) if fresh else -1
            while True:
                latest = self._latest.get(topic)
                if self._seq.get(topic, 0) != seen and latest is not None:
                    seen = self._seq.get(topic, 0)
                    if predicate(latest):
                        return latest
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise CommandTimeoutError(
                        f"no {topic!r} message matching the condition within {timeout:.1f} s"
                    )
                self._conds.wait(remaining)
