"""The command side of the robot client: `Commander` sends arbiter commands and holds the lease.

Every command returns the arbiter's *applied* map or raises a :class:`schemas.errors.CommandError`
(``LeaseBusyError``, ``InvalidCommandError``, ``RateLimitedError``…) or a
:class:`schemas.errors.ClientError`.

The lease is bound to this object: ``acquire`` keeps the secret token the daemon returns (to this
caller alone), every command carries it, and a background thread renews the lease with it every
0.4 s while it is held (the daemon ends a silent holder's lease with a safe stop).

:class:`clients.robot.Robot` adds the watching side (state, subscriptions) to it.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
import weakref
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any, Self

import zenoh

from clients.lease_keeper import LeaseKeeper
from clients.protocol_watch import ProtocolWatch
from schemas.errors import (
    ClientError,
    CommandError,
    LeaseBusyError,
    NoLeaseError,
    RateLimitedError,
    RobotUnreachableError,
)
from schemas.keys import Keys
from schemas.messages import command_payload
from schemas.query import ask
from schemas.roles import LADDER, Role, command_key, discover_role, parse_role, required_role
from schemas.roles import check as check_role
from schemas.session import CONNECT_HINT, Credentials, Target, connect, login_hint, resolve
from schemas.session import credentials as make_credentials

if TYPE_CHECKING:
    from clients.calibration import OffsetTuner

# Clients not yet closed, closed when the interpreter ends. Zenoh runs each subscriber's callback
# in a Python thread that is not a daemon thread and lives until the subscriber is undeclared,
# so a script that forgets ``close()`` would otherwise never exit: Python joins those threads
# before it runs ``atexit`` handlers. ``threading._register_atexit`` runs before that join (as
# concurrent.futures uses it); closing releases the lease (a safe stop) and the session.
_OPEN: weakref.WeakSet[Commander] = weakref.WeakSet()


def _close_open_clients() -> None:
    for client in list(_OPEN):
        with contextlib.suppress(Exception):
            client.close()


threading._register_atexit(_close_open_clients)  # type: ignore[attr-defined]


def _matching(querier: zenoh.Querier) -> bool:
    """Whether a queryable matching ``querier`` is known. eclipse-zenoh 1.10.2 returns a
    ``MatchingStatus`` where its stub says ``bool``: either is read."""
    status: Any = querier.matching_status
    return bool(getattr(status, "matching", status))


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
        # 12 random hex digits, as a uuid4's first twelve are, without the uuid module (which
        # loads `platform` with it: ~7 ms of CPU at the start of every client).
        self.client_id = client_id or os.urandom(6).hex()
        self.name = name or f"python-{self.client_id[:6]}"
        self.timeout = timeout
        self._own_session = session is None
        self.session = session or connect(
            self.target, hint=CONNECT_HINT + login_hint(self.target.credentials)
        )
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
        # A querier per command key, asked only whether a queryable there is known (its matching
        # status); the query itself goes through ``ask``. ``_reached``: one was known once.
        self._queriers: dict[str, zenoh.Querier] = {}
        self._queriers_lock = threading.Lock()  # the renewal thread sends commands too
        self._reached = False
        # The lease secret while we hold the lease, renewed from a thread.
        self._lease = LeaseKeeper(
            lambda: self.command("lease", timeout=1.0, op="renew"), self.client_id
        )
        # The arbiter releases our lease (and safely stops the robot) when this token goes.
        self._token = self.session.liveliness().declare_token(self.keys.client(self.client_id))
        _OPEN.add(self)
        self._open_extra()

    def _open_extra(self) -> None:
        """What a subclass adds once the session is open (its pair: ``_close_extra``)."""

    def close(self) -> None:
        if self._closed:
            return
        self._lease.drop()
        self._closed = True
        _OPEN.discard(self)
        self._close_extra()
        with self._queriers_lock:
            for querier in self._queriers.values():
                with contextlib.suppress(Exception):
                    querier.undeclare()
            self._queriers.clear()
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
        """Send one arbiter command; return its *applied* map or raise. Sent once; while this
        session re-establishes its link to a robot it reached before, it first waits (within
        ``timeout``) for the robot's command key to be declared again (docs/links.md)."""
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
                f"{self.target.robot!r} running (`darwin up`), and is the robot name right? "
                "(docs/troubleshooting.md#no-robot-found)"
            )

        budget = timeout or self.timeout
        deadline = time.monotonic() + budget
        self._await_route(key, deadline)
        # What the wait for a route left of the timeout (a moment at least: with no route the
        # query is answered at once, with no reply).
        budget = max(deadline - time.monotonic(), 0.001)
        try:
            while True:
                try:
                    applied = ask(
                        self.session, key, payload, budget, verb=verb, unreachable=unreachable
                    )
                    self._reached = True
                    break
                except RateLimitedError as exc:
                    # Throttled, nothing applied: wait as told while the timeout allows.
                    self._reached = True
                    wait = exc.retry_after or 0.05
                    if time.monotonic() + wait >= deadline:
                        raise
                    time.sleep(wait)
                except CommandError:
                    self._reached = True  # the daemon answered, with an error
                    raise
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

    def _await_route(self, key: str, deadline: float) -> None:
        """Wait, until ``deadline`` at most, for this session to know a queryable on ``key`` again
        when it knew one before: the link to the robot is being re-established.

        A session whose link failed reconnects by itself, and until the daemon's queryables are
        declared to it again a query goes nowhere: Zenoh answers it at once with no reply. Sent
        then, every command in the gap failed in microseconds as "nobody answers" (on a lossy
        link, 14 in 5 ms within a reconnect of 4 s, docs/links.md) though the robot was back
        within the next command's timeout. Waiting for the route before sending keeps each
        command sent once: a query that did go out is never sent again (its reply may be what
        was lost). A key never served through this session (a wrong robot name, no daemon yet)
        still fails at once, as before."""
        try:
            with self._queriers_lock:
                querier = self._queriers.get(key)
                if querier is None:
                    querier = self._queriers[key] = self.session.declare_querier(key)
        except zenoh.ZError:
            return  # the session failed: ``ask`` says so
        if _matching(querier):
            self._reached = True
            return
        if not self._reached:
            return
        known = threading.Event()
        listener = querier.declare_matching_listener(
            lambda status: known.set() if status.matching else None
        )
        try:
            # Asked again once the listener is there: a route declared meanwhile is not missed.
            if not _matching(querier):
                known.wait(max(0.0, deadline - time.monotonic()))
        finally:
            with contextlib.suppress(Exception):
                listener.undeclare()

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
            # Loaded on first use: with the user file's writer it costs a client (the gateway
            # at each start) ~10 ms of CPU, and few clients edit offsets.
            from clients.calibration import OffsetTuner

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

    def power(self, on: bool) -> dict[str, Any]:
        """Power the servos again after the CM-730's reset button (``on``), or cut their power
        (every servo limp at once). Admin only, under the lease."""
        return self.command("power", op="on" if on else "off")

    def led(
        self,
        head: tuple[int, int, int] | None = None,
        eye: tuple[int, int, int] | None = None,
        panel: int | None = None,
    ) -> dict[str, Any]:
        fields: dict[str, Any] = {
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
        if isinstance(page, int):
            return self.command("action", op="play", page=page)
        return self.command("action", op="play", name=page)

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
