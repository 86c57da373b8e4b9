"""The `Robot` client: connect, latest state, subscribe, commands, the control lease.

    >>> from clients import Robot
    >>> with Robot() as robot:                 # DARWIN_ENDPOINT / DARWIN_ROBOT or local defaults
    ...     print(robot.state.joints.position)
    ...     with robot.control("my notebook"):
    ...         robot.joint("head_pan", 0.3)

Every command returns the arbiter's *applied* map or raises a :class:`schemas.errors.CommandError`
(``LeaseBusyError``, ``InvalidCommandError``, ``RateLimitedError``…) or a
:class:`schemas.errors.ClientError`.

The lease is bound to this object: ``acquire`` keeps the secret token the daemon returns (to this
caller alone), every command carries it, and a background thread renews the lease with it every
0.4 s while it is held (the daemon ends a silent holder's lease with a safe stop).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, Self

import zenoh

from clients.calibration import OffsetTuner
from clients.fleet import RobotRecord, discover_at
from clients.lease_keeper import LeaseKeeper
from clients.protocol_watch import ProtocolWatch
from clients.teach import TeachMixin
from schemas.errors import (
    ClientError,
    CommandTimeoutError,
    LeaseBusyError,
    NoLeaseError,
    ProtocolError,
    RateLimitedError,
    RobotUnreachableError,
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
)
from schemas.query import ask
from schemas.roles import LADDER, Role, command_key, discover_role, parse_role, required_role
from schemas.roles import check as check_role
from schemas.session import Credentials, Target, login_hint, open_client, resolve
from schemas.session import credentials as make_credentials

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

    def __init__(self, robot: Robot, topic: str, callback: Callable[[Message], None]) -> None:
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


class Commander:
    """Commands and the lease, without any subscription: one per legacy connection in the
    gateway, many sharing one Zenoh session (pass ``session``)."""

    protocol: ProtocolWatch | None = None  # a Robot's watch on the daemon's versions

    def __init__(
        self,
        endpoint: str | None = None,
        robot: str | None = None,
        *,
        name: str | None = None,
        client_id: str | None = None,
        timeout: float = 3.0,
        session: zenoh.Session | None = None,
        user: str | None = None,
        password: str | None = None,
        credentials: Credentials | None = None,
        role: Role | str | None = None,
    ) -> None:
        if session is not None:
            credentials = Credentials()  # the session is open: who it is was settled there
        elif credentials is None and (user or password):
            credentials = make_credentials(user=user, password=password)
        self.target: Target = resolve(endpoint, robot, credentials)
        self.keys = Keys(self.target.robot)
        self.client_id = client_id or uuid.uuid4().hex[:12]
        self.name = name or f"python-{self.client_id[:6]}"
        self.timeout = timeout
        self._own_session = session is None
        try:
            self.session = session or open_client(self.target)
        except zenoh.ZError as exc:
            raise RobotUnreachableError(
                f"cannot open a Zenoh session to {self.target.endpoint}: {exc}. "
                f"Is the daemon running there (`darwin up`)? Check --connect / DARWIN_ENDPOINT"
                f"{login_hint(self.target.credentials)}"
            ) from exc
        # The role is what the robot's access control grants us, learnt from it on first need
        # (``role``); ``role`` given caps it (a gateway running with --role observer).
        self._role: Role | None = None
        self._identity = ""  # who we logged in as, for messages
        with contextlib.suppress(OSError, ValueError):
            creds = self.target.credentials
            self._identity = (creds.identity if creds else None) or ""
        self._role_asked = False  # asked once: a daemon without role keys is not asked again
        self._role_cap: Role | None = parse_role(role, people_only=True) if role else None
        self._closed = False
        self._tuner: OffsetTuner | None = None
        # The lease secret while we hold the lease, renewed from a thread.
        self._lease = LeaseKeeper(
            lambda: self.command("lease", timeout=1.0, op="renew"), self.client_id
        )
        # The arbiter releases our lease (and safely stops the robot) when this token goes.
        self._token = self.session.liveliness().declare_token(self.keys.client(self.client_id))
        self._open_extra()

    def _open_extra(self) -> None:
        """What a subclass adds once the session is open (its pair: ``_close_extra``)."""

    def close(self) -> None:
        if self._closed:
            return
        self._lease.drop()
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
        if self.protocol is not None and verb != "halt":  # halt is always tried
            self.protocol.refuse()
        key = command_key(self.keys, verb, fields)
        if required_role(verb, fields) != Role.OBSERVER:
            # Refused here at once, naming the role that may: access control would drop the
            # query silently (no reply), which looks like an unreachable robot.
            check_role(self.role, verb, fields, self._identity)
        envelope: dict[str, Any] = {"client_name": self.name}
        token = self._lease.token
        if token is not None:
            envelope["lease_token"] = token
        # The human name travels as ``client_name``: ``name`` is a verb field (joint, action…).
        payload = command_payload(self.client_id, **envelope, **fields)

        def unreachable() -> Exception:
            return RobotUnreachableError(
                f"nobody answers {key} at {self.target.endpoint}: is the daemon for robot "
                f"{self.target.robot!r} running (`darwin up`), and is the robot name right?"
            )

        budget = timeout or self.timeout
        deadline = time.monotonic() + budget
        try:
            while True:
                try:
                    applied = ask(
                        self.session, key, payload, budget, verb=verb, unreachable=unreachable
                    )
                    break
                except RateLimitedError as exc:
                    # Throttled, nothing applied: wait as told while the timeout allows.
                    wait = exc.retry_after or 0.05
                    if time.monotonic() + wait >= deadline:
                        raise
                    time.sleep(wait)
        except (NoLeaseError, LeaseBusyError) as exc:
            if exc.field in ("client", "lease_token") and token is not None:
                self._lease.lost(token)  # the daemon ended our lease meanwhile
            raise
        if verb == "lease":
            # However the lease is taken (acquire(), control(), or command("lease", …) as the
            # TUI does), the secret stays with this client alone and is renewed.
            secret = applied.pop("token", None)
            if fields.get("op") == "acquire" and isinstance(secret, str):
                self._lease.hold(secret)
            elif fields.get("op") == "release":
                self._lease.drop()
        return applied

    @property
    def role(self) -> Role | None:
        """This client's role as the robot's access control sees it (None: unknown, e.g. an
        older daemon): the highest of the daemon's per-role keys that answers us."""
        if not self._role_asked:
            self._role = discover_role(self.session, self.keys, min(self.timeout, 2.0))
            # An answer is final; none (the robot not up yet) is asked again next time.
            self._role_asked = self._role is not None
        if self._role_cap is None:
            return self._role
        if self._role is None:
            return self._role_cap
        return min(self._role, self._role_cap, key=LADDER.index)

    @property
    def holds_lease(self) -> bool:
        """True while this client believes it holds the lease (it renews it)."""
        return self._lease.token is not None

    def acquire(self) -> dict[str, Any]:
        return self.command("lease", op="acquire")

    def release(self) -> dict[str, Any]:
        try:
            return self.command("lease", op="release")
        finally:
            self._lease.drop()

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

    @property
    def calibration(self) -> OffsetTuner:
        """Offsets: read, nudge, mirror, undo, save (:mod:`clients.calibration`; setting is
        admin only)."""
        if self._tuner is None:
            self._tuner = OffsetTuner(self)
        return self._tuner

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

    # -- motion helpers (walk, action, choreography, ball play, head) ---------------------------
    def walk(self, x: float = 0.0, y: float = 0.0, turn: float = 0.0) -> dict[str, Any]:
        """Walk (or change the walking speed): ``x`` forward and ``y`` left in m/s, ``turn``
        rad/s counter-clockwise. ``walk_stop()`` stops; ``halt()`` always does."""
        return self.command("walk", op="start", x=x, y=y, turn=turn)

    def walk_stop(self) -> dict[str, Any]:
        return self.command("walk", op="stop")

    def action(self, page: int | str) -> dict[str, Any]:
        """Play an action page by number or by name (e.g. ``"sit down"``)."""
        field_ = "page" if isinstance(page, int) else "name"
        return self.command("action", op="play", **{field_: page})

    def action_stop(self, brake: bool = False) -> dict[str, Any]:
        return self.command("action", op="brake" if brake else "stop")

    def choreography(self, items: list[dict[str, Any]]) -> dict[str, Any]:
        """Play behaviours in sequence: ``[{"behaviour": id, ...params}, …]`` (see
        :mod:`schemas.commands`)."""
        return self.command("choreography", op="play", items=list(items))

    def choreography_stop(self) -> dict[str, Any]:
        return self.command("choreography", op="stop")

    def playball(self, color: str = "red") -> dict[str, Any]:
        return self.command("playball", op="start", color=color)

    def playball_stop(self) -> dict[str, Any]:
        return self.command("playball", op="stop")

    def head(self, pan: float, tilt: float) -> dict[str, Any]:
        return self.command("head", pan=pan, tilt=tilt)

    def trajectory(
        self, joints: list[int | str], points: list[tuple[float, list[float]]]
    ) -> dict[str, Any]:
        """Play a joint trajectory in the daemon's loop: ``points`` are (seconds from the start,
        [rad per joint]), linear in between. Checked whole before anything moves."""
        return self.command(
            "trajectory",
            joints=list(joints),
            points=[{"t": float(t), "positions": [float(p) for p in pos]} for t, pos in points],
        )

    def trajectory_stop(self) -> dict[str, Any]:
        return self.command("trajectory", op="stop")

    def walk_params(self, **values: float) -> dict[str, Any]:
        """The gait parameters (``config/walking.toml`` names and units); with values, set them
        (needs the lease; each is checked against its range)."""
        return self.command("walk_params", set=values) if values else self.command("walk_params")

    def say(self, text: str, lang: str = "en") -> dict[str, Any]:
        return self.command("sound", say=text, lang=lang)

    def play_sound(self, file: str) -> dict[str, Any]:
        """Play a sound file on the robot (a path on the robot's disk)."""
        return self.command("sound", file=file)

    def behaviours(self) -> dict[str, Any]:
        """The behaviour library and the legacy ``type`` table (no lease needed)."""
        return self.command("behaviours")


class Robot(Commander, TeachMixin):
    """Commands plus the robot's live state and subscriptions; action pages and teach mode
    (:mod:`clients.teach`)."""

    def _open_extra(self) -> None:
        self._lock = threading.Lock()
        self._state = RobotState()
        self._listeners: dict[str, list[Subscription]] = {}
        self._zsubs: dict[str, Any] = {}
        self._conds = threading.Condition()
        self._seq: dict[str, int] = {}
        self._latest: dict[str, Message] = {}
        self.protocol = ProtocolWatch(f"this client ({self.name})")
        for topic in ALWAYS:
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
        with self._lock:
            return RobotState(**vars(self._state))

    def _on_sample(self, topic: str, sample: zenoh.Sample) -> None:
        try:
            msg = decode(sample.payload.to_bytes(), TOPICS[topic])
        except ProtocolError:
            if topic == "status":  # another protocol major: the watch says which
                self.protocol.observe(sample.payload.to_bytes())
            return  # a foreign or newer publisher: ignore rather than crash the callback
        if topic == "status":
            self.protocol.observe(vars(msg))
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
            sub._deliver(msg)

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
        :func:`clients.notebook.frames.to_frame`."""
        from clients.notebook.frames import to_frame

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
        from clients.notebook.frames import decode_jpeg

        return decode_jpeg(frames[0].jpeg)  # type: ignore[attr-defined]
