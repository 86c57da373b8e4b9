"""The client side of the policy stream: start it (``policy`` op=start, with the lease), read
observations, send signed actions, collect what the daemon applied.

    with robot.control():
        stream = PolicyStream(robot)
        stream.stand()
        stream.start(rate_hz=50)
        obs = stream.next_observation()
        applied = stream.send([0.0] * 20, obs.tick, wait=True)
        stream.stop()

A policy's actions are offsets from the contract's default pose and it was trained standing
there, but a stream starts by holding the present pose: :meth:`PolicyStream.stand` first brings
the robot there (the stand page, then at rest), as ``darwin policy run`` does.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections import deque
from collections.abc import Sequence
from typing import Any

from schemas import qos
from schemas.errors import DarwinError, ProtocolError
from schemas.joints import JOINT_NAMES
from schemas.messages import Event, decode, encode
from schemas.policy import PolicyAction, PolicyApplied, PolicyObservation, PolicyStatus

# ROBOTIS's page 1: its last step is the contract's DEFAULT_POSE (schemas/policy.py).
STAND_PAGE = "stand"
AT_POSE_RAD = 0.05  # every joint this close to the default pose: the robot stands there already
# At rest: over REST_S of the daemon's clock the gravity estimate moved less than REST_TILT_DEG
# and no gyro axis read more than REST_GYRO (rad/s). The estimate is the attitude filter's
# (tau 0.5 s): a page's last lean takes ~1.5 s to settle in it, and a policy started before
# answers a tilt that is not there.
REST_S = 0.3
REST_TILT_DEG = 0.3
REST_GYRO = 0.15
STAND_TIMEOUT = 15.0  # s: the page (~1 s) and coming to rest, with a loaded machine's margin


class PolicyStream:
    def __init__(self, robot: Any) -> None:
        self.robot = robot
        self.keys = robot.keys
        self.info: dict[str, Any] = {}
        self.seq = 0
        self._key = b""
        self._cond = threading.Condition()
        self._obs: PolicyObservation | None = None
        self._started = -1  # the tick the stream started at (observations after it are its)
        self._applied: dict[int, PolicyApplied] = {}
        self.applied: deque[PolicyApplied] = deque(maxlen=10000)
        self.status: PolicyStatus | None = None
        s = robot.session
        action = self.keys.policy("action")
        self._pub = s.declare_publisher(action, **qos.for_key(action).kwargs())
        self._subs = [
            s.declare_subscriber(self.keys.policy("obs"), self._on_obs),
            s.declare_subscriber(self.keys.policy("applied"), self._on_applied),
            s.declare_subscriber(self.keys.policy("status"), self._on_status),
        ]

    # -- subscriptions --------------------------------------------------------------------
    def _on_obs(self, sample: Any) -> None:
        try:
            obs = PolicyObservation.parse(sample.payload.to_bytes())
        except ProtocolError:
            return
        with self._cond:
            self._obs = obs
            self._cond.notify_all()

    def _on_applied(self, sample: Any) -> None:
        try:
            msg = decode(sample.payload.to_bytes(), PolicyApplied)
        except ProtocolError:
            return
        assert isinstance(msg, PolicyApplied)
        with self._cond:
            self.applied.append(msg)
            self._applied[msg.seq] = msg
            if len(self._applied) > 1000:
                self._applied.pop(next(iter(self._applied)))
            self._cond.notify_all()

    def _on_status(self, sample: Any) -> None:
        with contextlib.suppress(ProtocolError):
            msg = decode(sample.payload.to_bytes(), PolicyStatus)
            assert isinstance(msg, PolicyStatus)
            self.status = msg

    # -- the stream -----------------------------------------------------------------------
    def start(self, rate_hz: float | None = None, mode: str = "offset", scale: float | None = None):
        fields: dict[str, Any] = {"op": "start", "mode": mode}
        if rate_hz is not None:
            fields["rate_hz"] = rate_hz
        if scale is not None:
            fields["scale"] = scale
        self.info = self.robot.command("policy", **fields)
        self._key = bytes(self.info["stream_key"])
        with self._cond:
            # An observation received before (of no stream, or of one that ended) is not one
            # of this stream: it would say the stream is not running.
            self._started = int(self.info.get("tick", -1))
        return self

    def stop(self) -> dict[str, Any]:
        return self.robot.command("policy", op="stop")

    def stand(self, timeout: float = STAND_TIMEOUT) -> str:
        """Bring the robot (whose lease this client holds) to the contract's default pose at
        rest, before :meth:`start`: a stream holds the present pose, so from anywhere else
        the first actions would drive the joints there at ``max_delta`` per step, a jump that
        throws a standing robot over (after ``darwin up`` the servos are centred: legs
        straight, 0.93 rad from the default pose at the knees). Plays the stand page when
        any joint is more than ``AT_POSE_RAD`` off, waits for it to end, then for the robot
        to be at rest. Returns what it did, in one line. ``DarwinError`` when the page does
        not end or the robot does not come to rest within ``timeout``."""
        deadline = time.monotonic() + timeout
        obs = self._observation(-1, deadline, "an observation")
        off = [abs(v) for v in obs.joint_pos]
        worst = max(range(len(off)), key=off.__getitem__)
        did = f"at the default pose (within {AT_POSE_RAD:g} rad)"
        if off[worst] > AT_POSE_RAD:
            self._play_stand(deadline)
            did = (f"played the {STAND_PAGE} page ({JOINT_NAMES[worst]} was "
                   f"{off[worst]:.2f} rad from the default pose)")  # fmt: skip
        self._at_rest(deadline)
        return did

    def _play_stand(self, deadline: float) -> None:
        ends: list[tuple[int, str]] = []  # (page, how) of each page that ended
        cond = threading.Condition()

        def on_event(e: Event) -> None:
            if e.kind == "action" and e.data.get("state") != "started":
                with cond:
                    ends.append((int(e.data.get("page") or 0), str(e.data.get("state"))))
                    cond.notify_all()

        # Subscribed before the page is asked for: its end cannot come unseen.
        with self.robot.subscribe("events", on_event):
            page = int(self.robot.action(STAND_PAGE)["page"])
            with cond:
                cond.wait_for(lambda: any(p == page for p, _ in ends),
                              max(0.0, deadline - time.monotonic()))  # fmt: skip
                how = next((h for p, h in ends if p == page), None)
        if how is None:
            raise DarwinError(f"the {STAND_PAGE} page did not end in time: is the robot held?")
        if how != "finished":
            raise DarwinError(f"the {STAND_PAGE} page was {how}: run the policy again")

    def _at_rest(self, deadline: float) -> None:
        window: deque[PolicyObservation] = deque()
        tick = -1
        while True:
            obs = self._observation(tick, deadline, "the robot at rest")
            tick = obs.tick
            window.append(obs)
            while window[-1].stamp - window[0].stamp > REST_S:
                window.popleft()
            if window[-1].stamp - window[0].stamp < REST_S * 0.9:
                continue
            tilts = [math.degrees(math.acos(max(-1.0, min(1.0, -o.gravity[2])))) for o in window]
            gyro = max(abs(g) for o in window for g in o.gyro)
            if max(tilts) - min(tilts) < REST_TILT_DEG and gyro < REST_GYRO:
                return

    def _observation(self, after: int, deadline: float, what: str) -> PolicyObservation:
        # Observations without a stream: the daemon's `[policy] observe_hz`, ours subscribed.
        with self._cond:
            self._cond.wait_for(lambda: self._obs is not None and self._obs.tick > after,
                                max(0.0, deadline - time.monotonic()))  # fmt: skip
            obs = self._obs
        if obs is None or obs.tick <= after:
            raise DarwinError(f"no {what} from the daemon in time: is the robot held or moving?")
        return obs

    def next_observation(
        self, after_tick: int = -1, timeout: float = 2.0
    ) -> PolicyObservation | None:
        """The first observation newer than ``after_tick`` and than the stream's start (None
        after ``timeout``)."""
        with self._cond:
            after_tick = max(after_tick, self._started)
            self._cond.wait_for(lambda: self._obs is not None and self._obs.tick > after_tick,
                                timeout)  # fmt: skip
            obs = self._obs
        return obs if obs is not None and obs.tick > after_tick else None

    def send(
        self, action: Sequence[float], obs_tick: int = 0, wait: bool = False, timeout: float = 1.0
    ) -> PolicyApplied | None:
        """Publish one signed action; with ``wait``, the daemon's answer to it."""
        self.seq += 1
        msg = PolicyAction.signed(self.robot.client_id, self._key, self.seq, list(action), obs_tick)
        self._pub.put(encode(msg))
        return self.answer(self.seq, timeout) if wait else None

    def send_raw(self, payload: bytes) -> None:
        """Publish bytes as they are (tests of bad input)."""
        self._pub.put(payload)

    def answer(self, seq: int, timeout: float = 1.0) -> PolicyApplied | None:
        with self._cond:
            self._cond.wait_for(lambda: seq in self._applied, timeout)
            return self._applied.get(seq)

    def close(self) -> None:
        for x in (*self._subs, self._pub):
            with contextlib.suppress(Exception):
                x.undeclare()
