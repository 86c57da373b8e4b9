"""The policy loop: a client's stream of actions (schemas/policy.py) applied at the next tick.

``start`` (the ``policy`` verb, lease holder only) claims all 20 joints, holds the present pose
and returns a fresh stream key. Each action that passes :meth:`PolicyModule.offer` (signed with
that key, the holder's id, an increasing seq, not faster than the rate allows) waits in a
one-slot mailbox; the next tick turns it into joint targets, clipped to the robot config's
limits and to ``max_delta`` of change from the previous target, writes them and answers a
:class:`PolicyApplied` with what was applied. Without a new action for ``deadline_periods``
periods the targets hold (a missed deadline, counted), after ``damp_after`` s the joints go soft
(P gain ``damp_p``), and after ``silence_timeout`` s the stream ends with a safe stop (the
present pose held at the configured gains). A fall (gravity tilt past ``upright_min``), a joint
measured past its limit, or a temperature or voltage alarm also ends it: the same terminations
the simulator environment uses (clients/learn). Numpy only; the Zenoh side is
robot_daemon/engine/policy_link.py.
"""

from __future__ import annotations

import math
import secrets
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from config.loader import ranged, section_to
from robot_daemon.frames import JointFrame
from robot_daemon.motion.attitude import GravityFilter
from robot_daemon.motion.interface import MotionModule
from schemas.joints import JOINT_IDS, JOINT_NAMES
from schemas.policy import (
    ACTION_BOUND,
    DEFAULT_POSE,
    N_JOINTS,
    RATE_RANGE,
    PolicyAction,
    PolicyApplied,
    PolicyObservation,
    PolicyStatus,
)


@dataclass(frozen=True)
class PolicySettings:
    """``[policy]`` (config/motion.toml, where each is explained)."""

    rate_hz: float = ranged(50.0, RATE_RANGE[0], RATE_RANGE[1])
    observe_hz: float = ranged(50.0, 1.0, 125.0)
    max_delta: float = ranged(0.15, 0.001, 1.0)
    scale: float = ranged(0.3, 0.01, 1.0)
    deadline_periods: float = ranged(1.5, 1.0, 10.0)
    damp_after: float = ranged(0.1, 0.0, 5.0)
    damp_p: int = ranged(8, 0, 254)
    silence_timeout: float = ranged(0.5, 0.05, 10.0)
    burst: int = ranged(3, 1, 20)
    upright_min: float = ranged(0.85, -1.0, 1.0)
    limit_margin_deg: float = ranged(3.0, 0.0, 30.0)
    max_temperature: float = ranged(70.0, 20.0, 85.0)
    min_voltage: float = ranged(10.0, 0.0, 16.0)
    filter_tau: float = ranged(0.5, 0.0, 10.0)

    @classmethod
    def from_config(cls, section: dict[str, Any] | None) -> PolicySettings:
        return section_to(cls, section or {}, "policy")


IDX = np.array(JOINT_IDS)  # contract order → JointFrame slots
STATUS_PERIOD = 0.5  # s between PolicyStatus publications (and on every change of state)

# Health of the servos for the alarm termination: () → a reason, "" when fine (policy_link).
Health = Callable[[], str]
Sink = Callable[[str, Any], None]  # (topic, message) → published off the motion thread


class PolicyModule(MotionModule):
    name = "policy"

    def __init__(
        self, settings: PolicySettings | None = None, clock: Callable[[], float] = time.monotonic
    ) -> None:
        super().__init__()
        self.clock = clock  # the loop's clock (frame.time): simulated in tests
        self.settings = s = settings or PolicySettings()
        self.filter = GravityFilter(s.filter_tau)
        # Joint limits in contract order (rad), set from the robot config on attach.
        self.low = np.full(N_JOINTS, -math.pi)
        self.high = np.full(N_JOINTS, math.pi)
        self.default = np.array(DEFAULT_POSE)
        self.sink: Sink | None = None
        # Whether anyone listens to a topic of the sink (the daemon's Publishers.wanted): an
        # idle module builds no observation for nobody.
        self.wanted: Callable[[str], bool] = lambda topic: True
        self.health: Health | None = None
        self.command = [0.0, 0.0, 0.0]
        self._lock = threading.Lock()
        self._mail: tuple[PolicyAction, float] | None = None
        self._reset_stream()
        self.state = "idle"
        self.reason = ""
        self.counts: dict[str, Any] = dict.fromkeys(
            ("applied", "clipped", "missed", "overruns", "lost"), 0
        )
        self.refused: dict[str, int] = {}
        self.latencies: deque[float] = deque(maxlen=500)
        self._obs_stamps: deque[tuple[int, float]] = deque(maxlen=64)
        self._next_obs = 0.0
        self._next_status = 0.0
        self._status_state = ""
        self.started_tick = -1
        self.last_action = np.zeros(N_JOINTS)

    def _reset_stream(self) -> None:
        self.stream_key = b""
        self.client = ""
        self.rate_hz = self.settings.rate_hz
        self.mode = "offset"
        self.scale = self.settings.scale
        self._seq = -1
        self._tokens = 0.0
        self._token_at = 0.0
        # The newest observation published, and the newest one an accepted action answered.
        self._published_tick = 0
        self._answered_tick = 0

    def attach(self, manager: Any) -> None:
        super().attach(manager)
        robot = manager.robot
        self.low = np.array([robot.by_id[j].min_rad for j in JOINT_IDS])
        self.high = np.array([robot.by_id[j].max_rad for j in JOINT_IDS])

    # -- the stream (start: motion thread, through the verb; offer: the subscriber thread) ----
    def start(self, client: str, rate_hz: float, mode: str, scale: float) -> bytes:
        with self._lock:
            self._reset_stream()
            self.stream_key = secrets.token_bytes(16)
            self.client, self.rate_hz, self.mode, self.scale = client, rate_hz, mode, scale
            self._tokens = float(self.settings.burst)
            self._token_at = self.clock()
            self._answered_tick = self._published_tick
            self._mail = None
        frame = self.manager.last_frame if self.manager else None
        # Observations of later ticks are published after this start (they say `running`).
        self.started_tick = frame.tick if frame else -1
        present = frame.position[IDX] if frame else self.default
        self.target = np.clip(present, self.low, self.high)
        self.last_action = self._to_action(self.target)
        self.state, self.reason = "running", ""
        self._last_action_at = frame.time if frame else self.clock()
        self._missed_since = self._last_action_at
        self.claim(set(JOINT_IDS))
        self.emit("policy", f"policy stream of {client} started at {rate_hz:g} Hz", state="running")
        return self.stream_key

    def offer(self, action: PolicyAction) -> str:
        """Queue ``action`` for the next tick; "" when queued, else why it was refused."""
        now = self.clock()
        with self._lock:
            if not self.stream_key or self.state in ("idle", "stopped"):
                key, why = "no_stream", "no policy stream is running: start one (`policy` op=start)"
            elif action.client != self.client:
                key, why = "not_holder", f"client {action.client} is not the stream's holder"
            elif not action.verify(self.stream_key):
                key, why = "bad_mac", "the action's mac does not match the stream key"
            elif action.seq <= self._seq:
                # A replay, or one that came after a newer one (Zenoh keeps a link's messages
                # in order): too old to apply either way, and a late one stays counted lost.
                key, why = "old_seq", f"seq {action.seq} is not after {self._seq} (replayed?)"
            else:
                self._take_seq(action.seq)
                key, why = self._pace(action, now)
                if not key:
                    return self._accept(action, now)
            self.refused[key] = self.refused.get(key, 0) + 1
            return why

    def _take_seq(self, seq: int) -> None:
        # Actions travel droppable (schemas/qos.py): one dropped on the way is seen only as
        # the seqs a later one skips. Refused or not, an authenticated action's seq is the
        # stream's newest, so that a refusal is never also counted lost. The stream's first
        # action skips nothing: a client's seqs need not start at 1, only increase.
        if self._seq >= 0:
            self.counts["lost"] += seq - self._seq - 1
        self._seq = seq

    def _pace(self, action: PolicyAction, now: float) -> tuple[str, str]:
        """("", "") when ``action`` is within the stream's pace, else (refusal key, why)."""
        if 0 < action.obs_tick <= self._published_tick:
            # It answers an observation: paced by them, one action each. Not by when it
            # arrives: a loaded machine delivers actions sent 20 ms apart in bunches.
            if action.obs_tick <= self._answered_tick:
                return "too_fast", (
                    f"too fast: observation {action.obs_tick} was answered already (one "
                    f"action per observation, {self.rate_hz:g} Hz)"
                )
            self._answered_tick = action.obs_tick
            return "", ""
        rate = self.rate_hz * 1.25
        self._tokens = min(
            float(self.settings.burst), self._tokens + max(0.0, now - self._token_at) * rate
        )
        self._token_at = now
        if self._tokens < 1.0:
            return "too_fast", f"too fast: the stream runs at {self.rate_hz:g} Hz"
        self._tokens -= 1.0
        return "", ""

    def _accept(self, action: PolicyAction, now: float) -> str:
        if self._mail is not None:
            self.counts["overruns"] += 1  # the one before it was never applied
        self._mail = (action, now)
        return ""

    def set_command(self, x: float, y: float, turn: float) -> None:
        self.command = [float(x), float(y), float(turn)]

    # -- the tick --------------------------------------------------------------------------
    def observe(self, frame: JointFrame) -> None:
        self.filter.update(frame.gyro, frame.accel, frame.dt)
        period = 1.0 / (self.rate_hz if self.state != "idle" else self.settings.observe_hz)
        if frame.time + 1e-6 >= self._next_obs:
            self._next_obs = max(self._next_obs + period, frame.time + period / 2)
            self._publish_obs(frame)
        if self.sink is not None and (
            frame.time >= self._next_status or self.state != self._status_state
        ):
            self._next_status = frame.time + STATUS_PERIOD
            self._status_state = self.state
            self.sink("status", self.policy_status())

    def _publish_obs(self, frame: JointFrame) -> None:
        if self.sink is None or (self.state == "idle" and not self.wanted("obs")):
            return
        pos = (frame.position[IDX] - self.default).tolist()
        self._obs_stamps.append((frame.tick, frame.time))
        self._published_tick = frame.tick
        self.sink(
            "obs",
            PolicyObservation(
                joint_pos=pos,
                joint_vel=frame.velocity[IDX].tolist(),
                gyro=[float(v) for v in frame.gyro],
                gravity=list(self.filter.g),
                last_action=self.last_action.tolist(),
                command=list(self.command),
                stamp=frame.time,
                tick=frame.tick,
                running=self.state in ("running", "holding", "damping"),
            ),
        )

    def step(self, frame: JointFrame) -> dict[int, float]:
        if self.state not in ("running", "holding", "damping"):
            return {}
        why = self._termination(frame)
        if why:
            return self._safe_stop(frame, why)
        with self._lock:
            mail, self._mail = self._mail, None
        if mail is not None:
            self._apply(mail[0], frame)
        else:
            silent = frame.time - self._last_action_at
            period = 1.0 / self.rate_hz
            if silent > self.settings.silence_timeout:
                return self._safe_stop(frame, f"no action for {silent:.2f} s (silence)")
            if silent > self.settings.damp_after and self.state != "damping":
                self.state = "damping"
                self.emit("policy", "policy stream late: joints damped", state="damping")
            elif silent > self.settings.deadline_periods * period and self.state == "running":
                self.state = "holding"
            if frame.time - self._missed_since > self.settings.deadline_periods * period:
                self.counts["missed"] += 1
                self._missed_since = frame.time
        return dict(zip(JOINT_IDS, self.target.tolist(), strict=True))

    def _apply(self, action: PolicyAction, frame: JointFrame) -> None:
        a = np.array(action.action)
        clipped: list[str] = []
        if self.mode == "offset":
            if np.any(np.abs(a) > ACTION_BOUND):
                clipped.append(f"action outside ±{ACTION_BOUND:g}")
                a = np.clip(a, -ACTION_BOUND, ACTION_BOUND)
            want = self.default + self.scale * a
        else:
            want = a
        limited = np.clip(want, self.low, self.high)
        if np.any(limited != want):
            clipped.append("joint limits: " + _names(limited != want))
        step = np.clip(limited - self.target, -self.settings.max_delta, self.settings.max_delta)
        capped = self.target + step
        if np.any(np.abs(capped - limited) > 1e-12):
            clipped.append(
                f"max_delta {self.settings.max_delta:g} rad: " + _names(capped != limited)
            )
        self.target = capped
        self.last_action = self._to_action(capped)
        stamp = next((t for k, t in self._obs_stamps if k == action.obs_tick), None)
        latency = self.clock() - stamp if stamp is not None else 0.0
        if stamp is not None:
            self.latencies.append(latency)
        self._last_action_at = frame.time
        self._missed_since = frame.time
        if self.state != "running":
            self.emit("policy", "policy stream on time again", state="running")
        self.state = "running"
        self.counts["applied"] += 1
        self.counts["clipped"] += bool(clipped)
        if self.sink is not None:
            self.sink(
                "applied",
                PolicyApplied(
                    seq=action.seq,
                    action=self.last_action.tolist(),
                    target=self.target.tolist(),
                    clipped=clipped,
                    tick=frame.tick,
                    latency=latency,
                ),
            )

    def _to_action(self, target: np.ndarray) -> np.ndarray:
        if self.mode == "offset":
            return (target - self.default) / self.scale
        return target.copy()

    def _termination(self, frame: JointFrame) -> str:
        s = self.settings
        if self.filter.upright < s.upright_min:
            tilt = math.degrees(math.acos(max(-1.0, min(1.0, self.filter.upright))))
            return f"fall: tilt {tilt:.0f}°"
        pos = frame.position[IDX]
        online = frame.online[IDX].astype(bool)
        margin = math.radians(s.limit_margin_deg)
        hit = online & ((pos < self.low - margin) | (pos > self.high + margin))
        if hit.any():
            return "joint limit hit: " + _names(hit)
        return self.health() if self.health is not None else ""

    def _safe_stop(self, frame: JointFrame | None, reason: str) -> dict[int, float]:
        self.state, self.reason = "stopped", reason
        with self._lock:
            self._mail = None
            self.stream_key = b""
        self.release()
        if frame is not None and self.manager is not None:
            self.manager.hold_present(frame)
        self.emit("policy", f"policy stream stopped: {reason}", state="stopped", reason=reason)
        return {}

    # -- lifecycle -------------------------------------------------------------------------
    def gains(self) -> dict[int, tuple[int, int, int]]:
        if self.state != "damping" or self.manager is None:
            return {}
        robot = self.manager.robot
        p = self.settings.damp_p
        return {j: (min(p, robot.by_id[j].p), 0, robot.by_id[j].d) for j in JOINT_IDS}

    def stop(self) -> None:
        if self.state in ("running", "holding", "damping"):
            frame = self.manager.last_frame if self.manager else None
            self._safe_stop(frame, "stopped (lease ended, a fall, or op=stop)")

    def halt(self) -> None:
        if self.state in ("running", "holding", "damping"):
            self.state, self.reason = "stopped", "halt"
        with self._lock:
            self._mail = None
            self.stream_key = b""

    def on_released(self, ids: set[int]) -> None:
        if ids and self.state in ("running", "holding", "damping"):
            self.state, self.reason = "stopped", "another motion took the joints"
            with self._lock:
                self._mail = None
                self.stream_key = b""
            self.release()

    def policy_status(self) -> PolicyStatus:
        lat = sorted(self.latencies)

        def pct(q: float) -> float:
            return lat[min(len(lat) - 1, int(q * len(lat)))] * 1000 if lat else 0.0

        return PolicyStatus(
            state=self.state,
            reason=self.reason,
            holder=self.client,
            rate_hz=self.rate_hz,
            mode=self.mode,
            applied=self.counts["applied"],
            refused=dict(self.refused),
            clipped=self.counts["clipped"],
            missed_deadlines=self.counts["missed"],
            overruns=self.counts["overruns"],
            lost=self.counts["lost"],
            latency_p50_ms=round(pct(0.5), 3),
            latency_p99_ms=round(pct(0.99), 3),
        )

    def status(self) -> dict[str, Any]:
        return {"active": self.active, "state": self.state, "reason": self.reason}


def _names(mask: np.ndarray) -> str:
    return ", ".join(n for n, m in zip(JOINT_NAMES, mask, strict=True) if m)
