"""A ROS 2 node made of plain Zenoh entities, as rmw_zenoh builds one.

Publishers put CDR with the 33-byte attachment on the data key and hold an ``MP`` token;
transient-local publishers are zenoh-ext AdvancedPublishers with a cache and publisher detection
(rmw_zenoh ``rmw_publisher_data.cpp``), which is what a transient-local ROS subscriber's
AdvancedSubscriber queries for history. Subscriptions hold an ``MS`` token per accepted type.
Services are complete queryables on the service key with an ``SS`` token; the reply carries the
request's sequence number and the client's GID in its attachment (``rmw_service_data.cpp``).
"""

from __future__ import annotations

import contextlib
import functools
import logging
import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh
import zenoh.ext as zx

from clients.rmw import graph
from clients.rmw.attachment import Attachment, AttachmentError, Sequencer, gid_of
from clients.rmw.types import CdrError, dds_type, decode, encode, type_hash

log = logging.getLogger("darwin.ros2")

HEARTBEAT_S = 0.5  # rmw_zenoh's SAMPLE_MISS_DETECTION_HEARTBEAT_PERIOD (ms 500)


class Publisher:
    def __init__(self, node: RosNode, topic: str, ros_type: str, qos: graph.QoS) -> None:
        self.topic = topic
        self.ros_type = ros_type
        h = type_hash(ros_type)
        self.key = graph.data_key(node.domain, topic, dds_type(ros_type), h)
        self.token_key = node.info.entity_token(
            node.next_id(), graph.Kind.PUBLISHER, topic, dds_type(ros_type), h, qos
        )
        self._seq = Sequencer(gid_of(self.token_key))
        self._lock = threading.Lock()
        reliability = (
            zenoh.Reliability.RELIABLE
            if qos.reliability == graph.RELIABLE
            else zenoh.Reliability.BEST_EFFORT
        )
        if qos.durability == graph.TRANSIENT_LOCAL:
            miss = (
                zx.MissDetectionConfig(heartbeat=None, sporadic_heartbeat=HEARTBEAT_S)
                if qos.reliability == graph.RELIABLE
                else None
            )
            self._pub: Any = zx.declare_advanced_publisher(
                node.session,
                self.key,
                reliability=reliability,
                cache=zx.CacheConfig(qos.depth),
                publisher_detection=True,
                sample_miss_detection=miss,
            )
        else:
            self._pub = node.session.declare_publisher(self.key, reliability=reliability)
        self._token = node.session.liveliness().declare_token(self.token_key)

    def publish(self, msg: Any) -> None:
        self.publish_raw(encode(msg, self.ros_type))

    def publish_raw(self, payload: bytes) -> None:
        with self._lock:  # one sequence per publisher, in order
            self._pub.put(payload, attachment=self._seq.next())

    def close(self) -> None:
        for e in (self._token, self._pub):
            with contextlib.suppress(Exception):
                e.undeclare()


class Subscription:
    """Accepts one topic in several types (Twist and TwistStamped): one key and token each."""

    def __init__(
        self,
        node: RosNode,
        topic: str,
        ros_types: list[str],
        qos: graph.QoS,
        callback: Callable[[str, Any, Attachment], None],
        on_error: Callable[[str], None],
    ) -> None:
        self.topic = topic
        self._callback = callback
        self._on_error = on_error
        self._subs: list[Any] = []
        self._tokens: list[Any] = []
        for t in ros_types:
            h = type_hash(t)
            key = graph.data_key(node.domain, topic, dds_type(t), h)
            self._subs.append(
                node.session.declare_subscriber(key, functools.partial(self._on_sample, t))
            )
            tok = node.info.entity_token(
                node.next_id(), graph.Kind.SUBSCRIPTION, topic, dds_type(t), h, qos
            )
            self._tokens.append(node.session.liveliness().declare_token(tok))

    def _on_sample(self, ros_type: str, sample: zenoh.Sample) -> None:
        try:
            att = Attachment.decode(
                sample.attachment.to_bytes() if sample.attachment is not None else None
            )
            msg = decode(sample.payload.to_bytes(), ros_type)
        except (AttachmentError, CdrError) as exc:
            self._on_error(f"{self.topic}: dropped a sample: {exc}")
            return
        try:
            self._callback(ros_type, msg, att)
        except Exception as exc:  # a bug in a handler must not kill the Zenoh thread quietly
            log.exception("handler for %s failed", self.topic)
            self._on_error(f"{self.topic}: handler failed: {exc}")

    def close(self) -> None:
        for e in self._tokens + self._subs:
            with contextlib.suppress(Exception):
                e.undeclare()


class Service:
    """A service server: ``handler(request) -> response`` runs in a worker thread, never in
    Zenoh's callback, so a slow arbiter round trip does not block the network."""

    def __init__(
        self,
        node: RosNode,
        name: str,
        srv_type: str,
        handler: Callable[[Any], Any],
        on_error: Callable[[str], None],
    ) -> None:
        self.name = name
        self.srv_type = srv_type
        self._handler = handler
        self._on_error = on_error
        h = type_hash(srv_type)
        self.key = graph.data_key(node.domain, name, dds_type(srv_type), h)
        self._queryable = node.session.declare_queryable(self.key, self._on_query, complete=True)
        tok = node.info.entity_token(
            node.next_id(), graph.Kind.SERVICE, name, dds_type(srv_type), h, graph.SERVICE_QOS
        )
        self._token = node.session.liveliness().declare_token(tok)

    def _on_query(self, query: zenoh.Query) -> None:
        threading.Thread(target=self._serve, args=(query,), daemon=True).start()

    def _serve(self, query: zenoh.Query) -> None:
        with query:
            try:
                att = Attachment.decode(
                    query.attachment.to_bytes() if query.attachment is not None else None
                )
                payload = query.payload.to_bytes() if query.payload is not None else b""
                request = decode(payload, f"{self.srv_type}_Request")
            except (AttachmentError, CdrError) as exc:
                msg = f"{self.name}: bad request: {exc}"
                self._on_error(msg)
                query.reply_err(msg.encode())
                return
            try:
                response = self._handler(request)
            except Exception as exc:
                log.exception("service %s failed", self.name)
                query.reply_err(f"{self.name}: {exc}".encode())
                return
            reply_att = Attachment(att.sequence, time.time_ns(), att.gid).encode()
            query.reply(
                self.key,
                encode(response, f"{self.srv_type}_Response"),
                attachment=reply_att,
            )

    def close(self) -> None:
        for e in (self._token, self._queryable):
            with contextlib.suppress(Exception):
                e.undeclare()


class GraphWatch:
    """The domain's ROS graph from liveliness tokens: who subscribes to what."""

    def __init__(self, session: zenoh.Session, domain: int, on_change: Callable[[], None]) -> None:
        self._lock = threading.Lock()
        self._entities: dict[str, graph.Entity] = {}
        self._on_change = on_change
        self._sub = session.liveliness().declare_subscriber(
            graph.graph_selector(domain), self._on_token, history=True
        )

    def _on_token(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        with self._lock:
            if sample.kind == zenoh.SampleKind.DELETE:
                self._entities.pop(key, None)
            else:
                try:
                    self._entities[key] = graph.parse_token(key)
                except ValueError as exc:
                    log.debug("ignoring a token: %s", exc)
                    return
        self._on_change()

    def subscribers(self, topic: str, exclude_zid: str | None = None) -> int:
        with self._lock:
            return sum(
                1
                for e in self._entities.values()
                if e.kind is graph.Kind.SUBSCRIPTION
                and e.topic == topic
                and (exclude_zid is None or e.zid != exclude_zid)
            )

    def entities(self) -> list[graph.Entity]:
        with self._lock:
            return list(self._entities.values())

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._sub.undeclare()


class RosNode:
    """One ROS node on a Zenoh session: its token, entity ids and entities."""

    def __init__(
        self, session: zenoh.Session, domain: int, namespace: str, name: str, nid: int = 0
    ) -> None:
        self.session = session
        self.domain = domain
        self.namespace = graph.check_namespace(namespace)
        self.zid = str(session.zid())
        self.info = graph.Node(domain, self.zid, nid, self.namespace, name)
        self._next = nid + 1
        self._ids = threading.Lock()
        self._token = session.liveliness().declare_token(self.info.token())
        self._entities: list[Any] = []

    def next_id(self) -> int:
        with self._ids:
            n = self._next
            self._next += 1
            return n

    def name_of(self, relative: str) -> str:
        return graph.resolve(self.namespace, relative)

    def publisher(self, topic: str, ros_type: str, qos: graph.QoS) -> Publisher:
        p = Publisher(self, self.name_of(topic), ros_type, qos)
        self._entities.append(p)
        return p

    def subscription(self, topic: str, ros_types: list[str], qos: graph.QoS, callback, on_error):
        s = Subscription(self, self.name_of(topic), ros_types, qos, callback, on_error)
        self._entities.append(s)
        return s

    def service(self, name: str, srv_type: str, handler, on_error) -> Service:
        s = Service(self, self.name_of(name), srv_type, handler, on_error)
        self._entities.append(s)
        return s

    def close(self) -> None:
        for e in reversed(self._entities):
            e.close()
        self._entities.clear()
        with contextlib.suppress(Exception):
            self._token.undeclare()
