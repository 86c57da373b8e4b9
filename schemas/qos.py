"""Zenoh quality of service per key, defined once: what may be dropped and what goes first.

Every publisher and querier of the project takes its congestion control, priority and express
flag from :func:`for_key`, so video never delays control on a busy link:

- **halt and the lease** (``cmd/halt``, ``cmd/lease``): ``REAL_TIME``, never dropped.
  A reply travels with its query's QoS (zenoh 1.10: ``Query.reply``'s own QoS arguments are
  ignored, "to avoid priority inversion"), so the querier's QoS here is the reply's too.
  Not express: an express message takes a batch of its own, and a never-dropped message that
  finds its priority's few batches full (a link stalled by loss) blocks, then closes the link;
  batched, replies share a batch and wait at most Zenoh's 1 ms batching time.
- **other commands** (``cmd/*``, ``admin/*``): ``INTERACTIVE_HIGH``, never dropped.
- **reads and role probes** (``read/*``, ``role/*``): ``INTERACTIVE_LOW``, never dropped.
- **events and status** (newest-only status, one-off events): ``DATA_HIGH``, droppable.
- **bulk telemetry** (joints, imu at tick rate; vision detections; the policy stream's
  observations, actions and answers): ``DATA``, droppable, express (not held for a batch; each
  takes a batch of its own, so a listening session queues 8 of them, ``server_config``).
- **video and the simulated world** (camera JPEG, world snapshots, rendering): ``DATA_LOW``,
  droppable — a frame that cannot go out now is worth nothing later.

Zenoh keeps one transmission queue per priority on every link and empties the higher ones first;
a droppable message meeting a full queue is dropped instead of waiting (``wait_before_drop`` in
:func:`schemas.session.server_config`, which also keeps the kernel's send buffer small so that
the backlog stays in these queues), so a halt's reply does not queue behind camera frames.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import zenoh

from schemas.keys import ROOT

DROP = zenoh.CongestionControl.DROP
BLOCK = zenoh.CongestionControl.BLOCK


@dataclass(frozen=True)
class Qos:
    """How a kind of message travels on Zenoh: congestion control, priority, express."""

    congestion_control: zenoh.CongestionControl
    priority: zenoh.Priority
    express: bool = False

    @property
    def droppable(self) -> bool:
        return self.congestion_control == DROP

    def kwargs(self) -> dict[str, Any]:
        """Keyword arguments for ``declare_publisher``, ``session.get``, ``session.put``."""
        return {
            "congestion_control": self.congestion_control,
            "priority": self.priority,
            "express": self.express,
        }

    def lossless(self) -> Qos:
        """The same priority, never dropped (a replay must not differ from its recording)."""
        return Qos(BLOCK, self.priority, self.express)


SAFETY = Qos(BLOCK, zenoh.Priority.REAL_TIME)
COMMAND = Qos(BLOCK, zenoh.Priority.INTERACTIVE_HIGH)
READ = Qos(BLOCK, zenoh.Priority.INTERACTIVE_LOW)
EVENTS = Qos(DROP, zenoh.Priority.DATA_HIGH)
STATUS = Qos(DROP, zenoh.Priority.DATA_HIGH, express=True)
TELEMETRY = Qos(DROP, zenoh.Priority.DATA, express=True)
VIDEO = Qos(DROP, zenoh.Priority.DATA_LOW)
# The simulator's and the replay's control queryables: tooling, below commands; the simulator's
# camera frames come back as replies to ``render`` queries, so it sits with video (never
# dropped: a dropped reply would only make the caller wait for its timeout).
TOOLING = Qos(BLOCK, zenoh.Priority.DATA_LOW)

# The part of a key after ``darwin/<robot>/`` → its QoS. ``*`` ends match any last chunk.
_BY_SUFFIX: dict[str, Qos] = {
    "cmd/halt": SAFETY,
    "cmd/lease": SAFETY,
    "cmd/*": COMMAND,
    "admin/*": COMMAND,
    "read/*": READ,
    "role/*": READ,
    "events": EVENTS,
    "status": STATUS,
    "joints": TELEMETRY,
    "imu": TELEMETRY,
    "vision/ball": TELEMETRY,
    "policy/*": TELEMETRY,
    "camera/jpeg": VIDEO,
    "sim/world": VIDEO,
    "sim/control": TOOLING,
    "replay/control": TOOLING,
    "record/control": TOOLING,
}


def for_key(key: str) -> Qos:
    """The QoS of a ``darwin/<robot>/…`` key (publication or query); ``ValueError`` for a key
    this table does not know, so a new key cannot go out without a decision."""
    parts = key.split("/")
    if len(parts) < 3 or parts[0] != ROOT:
        raise ValueError(f"{key!r} is not a darwin/<robot>/… key")
    suffix = "/".join(parts[2:])
    qos = _BY_SUFFIX.get(suffix)
    if qos is None:
        qos = _BY_SUFFIX.get("/".join([*parts[2:-1], "*"]))
    if qos is None:
        raise ValueError(
            f"no QoS defined for {key!r}: add {suffix!r} to schemas/qos.py (known: "
            f"{', '.join(_BY_SUFFIX)})"
        )
    return qos


__all__ = ["BLOCK", "DROP", "Qos", "for_key"]
