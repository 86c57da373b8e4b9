"""The daemon's publications.

The tick's joints and IMU are sent from the motion thread itself (:meth:`Publishers.send`),
once its goals are written: they are droppable, and a droppable put waits at most
``wait_before_drop`` (50 µs, :func:`schemas.session.server_config`) for room on a congested
client's link, so a slow network costs a tick microseconds, never a period. Handing them to
another thread instead cost more than the put: a thread's wake-up and the GIL passed twice a
tick (~200 µs of CPU a tick on the benchmark machine, docs/loop-cpu.md).

Everything else goes through a publisher thread: status, events (a bounded FIFO, because each
one matters), vision's detections and the policy stream. Per slot topic only the newest
message waits (a stale frame is worth nothing).
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from typing import Any

import zenoh

from robot_daemon.engine.broadcast import as_payload
from schemas import qos
from schemas.keys import Keys
from schemas.messages import Event, Message

log = logging.getLogger(__name__)

# Topics the daemon publishes from the loop, by name → key property of ``Keys``.
LOOP_TOPICS = ("joints", "imu", "status")
# Newest-only topics: the loop's, and ball vision's detections (from its thread).
SLOT_TOPICS = (*LOOP_TOPICS, "vision_ball")


class Publishers:
    def __init__(self, session: zenoh.Session, keys: Keys) -> None:
        self.session = session
        self.keys = keys
        self._pubs: dict[str, zenoh.Publisher] = {}
        self._droppable: set[str] = set()  # the topics send() may put from the caller's thread
        for topic in SLOT_TOPICS:
            key = getattr(keys, topic)
            self._pubs[topic] = session.declare_publisher(key, **qos.for_key(key).kwargs())
            if qos.for_key(key).droppable:
                self._droppable.add(topic)
        # Events have a queue of their own on every link (a higher priority than the per-tick
        # topics, schemas/qos.py), so a burst of joints frames never crowds one out.
        self._pubs["events"] = session.declare_publisher(
            keys.events, **qos.for_key(keys.events).kwargs()
        )
        # Whether anyone subscribes, per loop topic, kept current by Zenoh's matching listeners:
        # asking ``matching_status`` costs tens of µs, twice a tick.
        self._matching: dict[str, bool] = {}
        self._listeners: list[Any] = []
        for topic in LOOP_TOPICS:
            self._watch(topic)
        self._slots: dict[str, Message] = {}
        self._fifo_topics: set[str] = set()
        self._fifo: deque[tuple[str, Message]] = deque(maxlen=256)
        self._events: deque[Event] = deque(maxlen=1000)
        self._cond = threading.Condition()
        self._stop = False
        self.dropped_events = 0  # the FIFO was full: status.loop.events_dropped
        self._event_seq = 0
        self._thread = threading.Thread(target=self._run, name="publisher", daemon=True)
        self._thread.start()

    def declare(self, topic: str, key: str, fifo: bool = False) -> None:
        """Another topic to ``post`` (the policy stream's); ``fifo``: every message is sent, in
        order (a bounded queue), instead of the newest only."""
        self._pubs[topic] = self.session.declare_publisher(key, **qos.for_key(key).kwargs())
        self._watch(topic)
        if fifo:
            self._fifo_topics.add(topic)

    def post(self, topic: str, msg: Message) -> None:
        """Hand ``msg`` to the publisher thread; a message of the same topic not yet sent is
        replaced (unless the topic was declared ``fifo``)."""
        with self._cond:
            if topic in self._fifo_topics:
                self._fifo.append((topic, msg))
            else:
                self._slots[topic] = msg
            self._cond.notify()

    def send(self, topic: str, msg: Message) -> None:
        """Encode and put ``msg`` now, in the caller's thread: for a droppable topic only
        (bounded by ``wait_before_drop``; a topic that may not be dropped would block)."""
        if topic not in self._droppable:
            raise ValueError(
                f"{topic!r} is not a droppable newest-only topic: post() it to the publisher thread"
            )
        self._put(topic, msg)

    def send_payload(self, topic: str, payload: bytes) -> None:
        """:meth:`send` of a message already encoded (``schemas/packed.py``)."""
        if topic not in self._droppable:
            raise ValueError(
                f"{topic!r} is not a droppable newest-only topic: post() it to the publisher thread"
            )
        try:
            self._pubs[topic].put(payload)
        except Exception:  # a closed session at shutdown
            log.exception("publishing %s failed", topic)

    def _watch(self, topic: str) -> None:
        pub = self._pubs[topic]

        def changed(status: Any) -> None:
            self._matching[topic] = bool(status.matching)

        try:
            self._listeners.append(pub.declare_matching_listener(changed))
            # zenoh's stubs type matching_status as a bool; it is a MatchingStatus.
            self._matching[topic] = bool(pub.matching_status.matching)  # type: ignore[attr-defined]
        except Exception:  # no listener: publish always, as when someone listens
            log.debug("no matching listener for %s", topic, exc_info=True)

    def wanted(self, topic: str) -> bool:
        """Whether any subscriber matches ``topic`` (as Zenoh's matching listener last said;
        True for a topic without one), so the loop builds no message for nobody."""
        return self._matching.get(topic, True)

    def event(self, kind: str, message: str, **data: Any) -> None:
        with self._cond:
            self._event_seq += 1
            if len(self._events) == self._events.maxlen:
                self.dropped_events += 1
            self._events.append(Event(kind=kind, message=message, data=data, seq=self._event_seq))
            self._cond.notify()

    def _run(self) -> None:
        while True:
            with self._cond:
                while not (self._slots or self._events or self._fifo or self._stop):
                    self._cond.wait()
                if self._stop and not (self._slots or self._events or self._fifo):
                    return
                slots, self._slots = self._slots, {}
                events = list(self._events)
                self._events.clear()
                fifo = list(self._fifo)
                self._fifo.clear()
            for ev in events:
                self._put("events", ev)
            for topic, msg in fifo:
                self._put(topic, msg)
            for topic, msg in slots.items():
                self._put(topic, msg)

    def _put(self, topic: str, msg: Message) -> None:
        try:
            self._pubs[topic].put(as_payload(msg))
        except Exception:  # a closed session at shutdown, a value msgpack refuses
            log.exception("publishing %s failed", topic)

    def close(self) -> None:
        with self._cond:
            self._stop = True
            self._cond.notify()
        self._thread.join(timeout=2.0)
        for listener in self._listeners:
            try:
                listener.undeclare()
            except Exception:
                log.debug("undeclare failed at shutdown", exc_info=True)
        for pub in self._pubs.values():
            try:
                pub.undeclare()
            except Exception:
                log.debug("undeclare failed at shutdown", exc_info=True)
