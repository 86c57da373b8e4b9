"""The learning contract: one observation and one action, the same in simulation and on the robot.

A policy sees :class:`PolicyObservation` (``darwin/<robot>/policy/obs``, published by the daemon at
the policy rate) and sends :class:`PolicyAction` (``darwin/<robot>/policy/action``, a publication
by the lease holder, authenticated per message, see below); the daemon answers each with
:class:`PolicyApplied` (``darwin/<robot>/policy/applied``): the action actually applied after
clipping, LeRobot's ``send_action`` convention. The Gymnasium environment (``clients/learn``),
the policy runner and the LeRobot plugin read these definitions and nothing else.

Joints are in id order (:data:`JOINT_NAMES`, ids 1..20), angles are servo angles in rad after
calibration (0 = raw 2048, the project's convention). Layout of the vectors:

===============  =====  ========  ============================================================
field            shape  unit      meaning
===============  =====  ========  ============================================================
joint_pos        20     rad       present position − :data:`DEFAULT_POSE`
joint_vel        20     rad/s     present velocity
gyro             3      rad/s     angular rate, body frame (robot x fore, y left, z up)
gravity          3      1         unit gravity direction in the body frame, (0, 0, −1) upright,
                                  from the daemon's attitude filter on the CM-730 gyro+accel
last_action      20     action    the last applied action, in the action's own units
command          3      m/s, rad/s  the commanded velocity x, y, turn (``policy`` op=command)
stamp            1      s         the daemon's monotonic clock when the sensors were read
tick             1      —         the daemon's tick counter at that read
===============  =====  ========  ============================================================

The action is 20 numbers in one of two modes (chosen by ``policy`` op=start): ``offset``
(default, MuJoCo Playground's OP3 convention): target = :data:`DEFAULT_POSE` + ``scale`` ×
action, action within [−1, 1]; ``absolute``: the targets in rad. Either way the daemon clips the
target to the joint limits of the robot config and to ``max_delta`` rad of change per policy
step, and says so in ``PolicyApplied.clipped``.

Why a publication and not a query per action: a query is a round trip through the arbiter's
queue (one per tick at most, answered by the replier thread), which puts a full network round
trip and up to a tick of queueing into every action at 50–125 Hz. A publication arrives in the
daemon's subscriber thread and waits in a one-slot mailbox for the next tick. The lease's token
must not travel in it (anyone subscribed to ``darwin/**`` would read it), so ``policy``
op=start, a query with the lease token, answers the holder alone with a fresh ``stream_key``;
each action carries ``mac`` = HMAC-SHA256(stream_key, :func:`action_body`)[:16] and an
increasing ``seq``. A copied or replayed action fails, and the stream ends with the lease.
"""

from __future__ import annotations

import hashlib
import hmac
import math
import time
from dataclasses import MISSING, dataclass, field, fields
from typing import Any, ClassVar

import msgpack

from schemas import SCHEMA_VERSION
from schemas.errors import ProtocolError, brief
from schemas.joints import JOINT_NAMES
from schemas.messages import Message, decode_dict, version_refusal
from schemas.units import raw_to_rad

N_JOINTS = len(JOINT_NAMES)
# The contract's own version (the observation, the action and their meaning), which a trained
# model records: the messages' schema version may change without it (2 dropped a field of the
# joints message no policy reads), so a model keeps working until this changes.
CONTRACT_VERSION = 1

# The default pose: ROBOTIS's page 1 "stand" (motion_4096.bin, last step; raw goals by id 1..20),
# knees bent 53°, arms down; the pose every offset action is relative to.
DEFAULT_POSE_RAW: tuple[int, ...] = (
    1502, 2594, 1843, 2253, 2389, 1707, 2048, 2048, 2058, 2038,
    1637, 2459, 2653, 1443, 2390, 1706, 2058, 2038, 2048, 2162,
)  # fmt: skip
DEFAULT_POSE: tuple[float, ...] = tuple(float(raw_to_rad(r)) for r in DEFAULT_POSE_RAW)

MODES = ("offset", "absolute")
DEFAULT_SCALE = 0.3  # rad per unit of an offset action (MuJoCo Playground OP3)
ACTION_BOUND = 1.0  # |offset action| ≤ this
RATE_RANGE = (25.0, 125.0)  # Hz a client may stream at
MAX_PAYLOAD_BYTES = 2048  # any policy message is far smaller; bigger ones are refused undecoded
MAC_BYTES = 16
MAX_CLIENT = 64

# Termination (the simulator env uses the same): upright measure −gravity_z below this.
UPRIGHT_MIN = 0.85  # MuJoCo Playground OP3's fall termination (≈ 32° of tilt)


def _floats(name: str, value: Any, n: int) -> list[float]:
    if not isinstance(value, list | tuple) or len(value) != n:
        got = f"{len(value)} values" if isinstance(value, list | tuple) else brief(value)
        raise ProtocolError(f"{name} must be a list of {n} numbers, got {got}")
    out = []
    for i, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise ProtocolError(f"{name}[{i}] must be a number, got {brief(v)}")
        if not math.isfinite(v):
            raise ProtocolError(f"{name}[{i}] is {v!r}: NaN and infinities are refused")
        out.append(float(v))
    return out


def decode_strict(payload: bytes, cls: type[Message]) -> dict[str, Any]:
    """The fields of a ``cls`` message in ``payload``: size, version, type and every field
    checked, an unknown or missing field refused by name (``ProtocolError``)."""
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise ProtocolError(f"{cls.TYPE} payload of {len(payload)} bytes is over the limit")
    d = decode_dict(payload)
    if d.get("v") != SCHEMA_VERSION:
        raise ProtocolError(version_refusal(d.get("v")))
    if d.get("type") != cls.TYPE:
        raise ProtocolError(f"expected a {cls.TYPE!r} message, got {brief(d.get('type'))}")
    names = {f.name for f in fields(cls)}
    for k in d:
        if k not in names and k not in ("v", "type"):
            raise ProtocolError(f"unknown field {brief(k)} in {cls.TYPE} (fields: {sorted(names)})")
    required = {
        f.name for f in fields(cls) if f.default is MISSING and f.default_factory is MISSING
    }
    for k in sorted(required - set(d)):
        raise ProtocolError(f"{cls.TYPE} lacks the field {k!r}")
    return {k: v for k, v in d.items() if k in names}


def action_body(seq: int, obs_tick: int, action: list[float]) -> bytes:
    """The bytes the ``mac`` of an action authenticates."""
    body: bytes = msgpack.packb([seq, obs_tick, action], use_bin_type=True)
    return body


def sign(stream_key: bytes, seq: int, obs_tick: int, action: list[float]) -> bytes:
    body = action_body(seq, obs_tick, action)
    return hmac.new(stream_key, body, hashlib.sha256).digest()[:MAC_BYTES]


@dataclass
class PolicyObservation(Message):
    """What a learned policy sees each tick: joints, IMU, gravity, its last action and the
    command."""

    TYPE: ClassVar[str] = "policy_obs"
    joint_pos: list[float]
    joint_vel: list[float]
    gyro: list[float]
    gravity: list[float]
    last_action: list[float]
    command: list[float]
    stamp: float = 0.0  # s, daemon monotonic clock at the sensor read
    tick: int = 0
    running: bool = False  # a policy stream is being applied

    SIZES: ClassVar[dict[str, int]] = {
        "joint_pos": N_JOINTS,
        "joint_vel": N_JOINTS,
        "gyro": 3,
        "gravity": 3,
        "last_action": N_JOINTS,
        "command": 3,
    }

    @classmethod
    def parse(cls, payload: bytes) -> PolicyObservation:
        d = decode_strict(payload, cls)
        for name, n in cls.SIZES.items():
            d[name] = _floats(name, d[name], n)
        return cls(**d)

    def vector(self) -> list[float]:
        """The flat observation, in :data:`OBSERVATION_LAYOUT` order."""
        return [*self.gyro, *self.gravity, *self.command, *self.joint_pos, *self.joint_vel,
                *self.last_action]  # fmt: skip


# Name, size of each slice of :meth:`PolicyObservation.vector` (Playground's order, plus velocity).
OBSERVATION_LAYOUT: tuple[tuple[str, int], ...] = (
    ("gyro", 3),
    ("gravity", 3),
    ("command", 3),
    ("joint_pos", N_JOINTS),
    ("joint_vel", N_JOINTS),
    ("last_action", N_JOINTS),
)
OBSERVATION_SIZE = sum(n for _, n in OBSERVATION_LAYOUT)
# Where each field lies in the vector.
OBSERVATION_SLICES: dict[str, slice] = {
    name: slice(at - n, at)
    for (name, n), at in zip(
        OBSERVATION_LAYOUT,
        [sum(n for _, n in OBSERVATION_LAYOUT[: i + 1]) for i in range(len(OBSERVATION_LAYOUT))],
        strict=True,
    )
}


@dataclass
class PolicyAction(Message):
    """A learned policy's action for one observation, from one client (signed when asked)."""

    TYPE: ClassVar[str] = "policy_action"
    client: str
    seq: int
    action: list[float]
    obs_tick: int = 0  # the observation's tick this action answers (latency, staleness)
    mac: bytes = b""

    @classmethod
    def parse(cls, payload: bytes) -> PolicyAction:
        d = decode_strict(payload, cls)
        if not isinstance(d["client"], str) or not 0 < len(d["client"]) <= MAX_CLIENT:
            raise ProtocolError(f"client must be a string of 1..{MAX_CLIENT} characters")
        for k in ("seq", "obs_tick"):
            v = d.get(k, 0)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise ProtocolError(f"{k} must be a non-negative integer, got {brief(v)}")
        if not isinstance(d.get("mac", b""), bytes):
            raise ProtocolError("mac must be bytes")
        d["action"] = _floats("action", d["action"], N_JOINTS)
        return cls(**d)

    @classmethod
    def signed(
        cls, client: str, stream_key: bytes, seq: int, action: list[float], obs_tick: int = 0
    ) -> PolicyAction:
        act = [float(a) for a in action]
        return cls(client, seq, act, obs_tick, sign(stream_key, seq, obs_tick, act))

    def verify(self, stream_key: bytes) -> bool:
        want = sign(stream_key, self.seq, self.obs_tick, self.action)
        return hmac.compare_digest(want, self.mac)


@dataclass
class PolicyApplied(Message):
    """What the daemon applied for action ``seq`` (or why it refused it: ``refused``)."""

    TYPE: ClassVar[str] = "policy_applied"
    seq: int
    action: list[float]  # the applied action, in the action's units (after clipping)
    target: list[float]  # the joint goals written, rad
    clipped: list[str] = field(default_factory=list)  # why it differs from what was sent
    refused: str = ""  # non-empty: the action was not applied, and why
    tick: int = 0
    latency: float = 0.0  # s, observation's sensor read → this action written
    stamp: float = field(default_factory=time.monotonic)


@dataclass
class PolicyStatus(Message):
    """The policy loop's counters (``darwin/<robot>/policy/status``, ~2 Hz and on change)."""

    TYPE: ClassVar[str] = "policy_status"
    state: str  # idle | running | holding | damping | stopped
    reason: str = ""  # why it stopped
    holder: str = ""
    rate_hz: float = 0.0
    mode: str = "offset"
    applied: int = 0
    refused: dict[str, int] = field(default_factory=dict)  # reason → count
    clipped: int = 0
    missed_deadlines: int = 0
    overruns: int = 0  # accepted actions a newer one replaced in the mailbox before a tick
    # Actions lost on the way (they travel droppable, schemas/qos.py): the seqs that an
    # authenticated action of the stream skipped; protocol 2.1 (docs/learning.md).
    lost: int = 0
    latency_p50_ms: float = 0.0
    latency_p99_ms: float = 0.0
    stamp: float = field(default_factory=time.monotonic)


def offset_to_target(action: list[float], scale: float) -> list[float]:
    return [d + scale * a for d, a in zip(DEFAULT_POSE, action, strict=True)]
