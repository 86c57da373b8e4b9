"""The client side of the policy stream: start it (``policy`` op=start, with the lease), read
observations, send signed actions, collect what the daemon applied.

    with robot.control():
        stream = PolicyStream(robot).start(rate_hz=50)
        obs = stream.next_observation()
        applied = stream.send([0.0] * 20, obs.tick, wait=True)
        stream.stop()
"""

from __future__ import annotations

import contextlib
import threading
from collections import deque
from collections.abc import Sequence
from typing import Any

from schemas import qos
from schemas.errors import ProtocolError
from schemas.messages import decode, encode
from schemas.policy import PolicyAction, PolicyApplied, PolicyObservation, PolicyStatus


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
