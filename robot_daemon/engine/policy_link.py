"""The policy stream's Zenoh side: the action subscriber, and the servo health it checks.

Actions arrive in Zenoh's callback thread, are decoded strictly (size, shape, NaN, unknown
fields: ``schemas.policy``) and offered to the policy module's one-slot mailbox; a refusal is
answered at once on ``…/policy/applied`` with ``refused`` set, so the sender learns why. What the
module publishes (observations, applied actions, status) goes through the daemon's publisher
thread: the motion thread never encodes or sends.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import zenoh

from robot_daemon.arbiter.lease import Lease
from robot_daemon.bus.tables import ErrorBit
from robot_daemon.engine.publishers import Publishers
from robot_daemon.motion.policy import PolicyModule
from schemas import qos
from schemas.errors import ProtocolError
from schemas.joints import JOINT_IDS, JOINT_NAMES
from schemas.keys import Keys
from schemas.messages import decode_dict, encode
from schemas.policy import (
    MAX_PAYLOAD_BYTES,
    N_JOINTS,
    PolicyAction,
    PolicyApplied,
)

log = logging.getLogger(__name__)

ALARM_BITS = ErrorBit.OVERHEATING | ErrorBit.INPUT_VOLTAGE


class PolicyLink:
    def __init__(
        self, session: zenoh.Session, keys: Keys, module: PolicyModule, pub: Publishers,
        state: Any, lease: Lease,
    ) -> None:  # fmt: skip
        self.module = module
        self.lease = lease
        self.state = state  # the bus's BusState: temperature, voltage, alarm by id
        self._ids = np.array(JOINT_IDS)
        for what in ("obs", "status"):
            pub.declare(f"policy_{what}", keys.policy(what))
        pub.declare("policy_applied", keys.policy("applied"), fifo=True)
        self.pub = pub
        applied = keys.policy("applied")
        self._refusals = session.declare_publisher(applied, **qos.for_key(applied).kwargs())
        module.sink = lambda topic, msg: pub.post(f"policy_{topic}", msg)
        module.wanted = lambda topic: pub.wanted(f"policy_{topic}")
        module.health = self.health
        self._sub = session.declare_subscriber(keys.policy("action"), self._on_action)

    def _on_action(self, sample: zenoh.Sample) -> None:
        payload = sample.payload.to_bytes()
        seq = -1
        try:
            action = PolicyAction.parse(payload)
            seq = action.seq
            holder = self.lease.holder
            if holder is None or holder.client != action.client:
                why = f"client {action.client} does not hold the control lease"
            else:
                why = self.module.offer(action)
        except ProtocolError as exc:
            seq = _seq_of(payload)  # so the sender can match the refusal to what it sent
            why = f"invalid action: {exc}"
            self.module.refused["invalid"] = self.module.refused.get("invalid", 0) + 1
        if why:
            self._refuse(seq, why)

    def _refuse(self, seq: int, why: str) -> None:
        zero = [0.0] * N_JOINTS
        msg = PolicyApplied(seq=seq, action=zero, target=zero, refused=why)
        try:
            self._refusals.put(encode(msg))
        except Exception:  # a closed session at shutdown
            log.debug("answering a refused action failed", exc_info=True)

    def health(self) -> str:
        """A temperature or voltage alarm on any servo, "" when there is none."""
        st, ids, s = self.state, self._ids, self.module.settings
        temp = st.temperature[ids]
        volts = st.voltage[ids]
        bits = st.alarm[ids] & int(ALARM_BITS)
        if (temp > s.max_temperature).any():
            k = int(np.argmax(temp))
            return f"temperature alarm: {JOINT_NAMES[k]} at {temp[k]:.0f} °C"
        low = (volts > 0) & (volts < s.min_voltage)
        if low.any():
            k = int(np.argmax(low))
            return f"voltage alarm: {JOINT_NAMES[k]} at {volts[k]:.1f} V"
        if bits.any():
            k = int(np.argmax(bits != 0))
            return f"servo alarm: {JOINT_NAMES[k]} reports error bits 0x{int(bits[k]):02x}"
        return ""

    def close(self) -> None:
        try:
            self._sub.undeclare()
        except Exception:
            log.debug("undeclare failed at shutdown", exc_info=True)
        try:
            self._refusals.undeclare()
        except Exception:
            log.debug("undeclare failed at shutdown", exc_info=True)


def _seq_of(payload: bytes) -> int:
    """The ``seq`` of a payload that failed to decode as an action, -1 when it has none."""
    if len(payload) > MAX_PAYLOAD_BYTES:
        return -1
    try:
        seq = decode_dict(payload).get("seq")
    except ProtocolError:
        return -1
    return seq if isinstance(seq, int) and not isinstance(seq, bool) and seq >= 0 else -1


def link_policy(
    session: zenoh.Session, keys: Keys, manager: Any, pub: Publishers, daemon: Any
) -> PolicyLink | None:
    """The link for the manager's policy module (None when this daemon runs without one)."""
    module = manager.get("policy")
    if not isinstance(module, PolicyModule):
        return None
    return PolicyLink(session, keys, module, pub, daemon.bus.state, daemon.lease)
