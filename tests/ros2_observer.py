"""An independent rmw_zenoh node for tests, written from rmw_zenoh's design document and
``src/detail`` sources, not from clients/ros2: what a ROS 2 Jazzy process would put on and read
from Zenoh. It shares only the CDR codec (rosbags, the reference implementation) with the adapter.

    obs = RmwObserver(session, domain=0)
    obs.wait_for(lambda g: any(e["kind"] == "MP" and e["topic"] == "/op1/joint_states" …))
"""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Callable
from typing import Any

import xxhash
import zenoh
import zenoh.ext as zx
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

STORE = get_typestore(Stores.ROS2_JAZZY)
# Request/response bodies of std_srvs/Trigger (only the CDR layout matters here, not the name).
STORE.register(
    get_types_from_msg("uint8 structure_needs_at_least_one_member", "std_srvs/msg/Trigger_Request")
)
STORE.register(get_types_from_msg("bool success\nstring message", "std_srvs/msg/Trigger_Response"))
STORE.register(get_types_from_msg("bool data", "std_srvs/msg/SetBool_Request"))
STORE.register(get_types_from_msg("bool success\nstring message", "std_srvs/msg/SetBool_Response"))

# Literals from the reference's table and rosidl-generated headers (not computed here).
HASH = {
    "sensor_msgs/msg/JointState": "RIHS01_a13ee3a330e346c9d87b5aa18d24e116"
    "90752bd33a0350f11c5882bc9179260e",
    "sensor_msgs/msg/Imu": "RIHS01_7d9a00ff131080897a5ec7e26e315954"
    "b8eae3353c3f995c55faf71574000b5b",
    "sensor_msgs/msg/CompressedImage": "RIHS01_15640771531571185e2efc8a100baf92"
    "3961a4d15d5569652e6cb6691e8e371a",
    "geometry_msgs/msg/Twist": "RIHS01_9c45bf16fe0983d80e3cfe750d683584"
    "3d265a9a6c46bd2e609fcddde6fb8d2a",
    "std_msgs/msg/String": "RIHS01_df668c740482bbd48fb39d76a70dfd4b"
    "d59db1288021743503259e948f6b1a18",
    "std_srvs/srv/Trigger": "RIHS01_eeff2cd6fa5ad9d27cdf4dec64818317"
    "839b62f212a91e6b5304b634b2062c5f",
    "trajectory_msgs/msg/JointTrajectory": "RIHS01_179b33eba59d676f6d967ac71fe35e7c"
    "a2f64b2f3928f4a018cec115e213796e",
    # Derived as rosidl does (request/response/event, ServiceEventInfo's char[16] as uint8[16]);
    # the same derivation reproduces the Trigger literal above.
    "std_srvs/srv/SetBool": "RIHS01_abe9e4bb6b41b40e6789712c00ec8871"
    "923e089af3f667a79992a428cff2da0a",
}


def dds(ros_type: str) -> str:
    pkg, kind, name = ros_type.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def gid(token: str) -> bytes:
    h = xxhash.xxh3_128_intdigest(token.encode())
    return struct.pack("<QQ", h & 0xFFFFFFFFFFFFFFFF, h >> 64)


def attachment(seq: int, g: bytes) -> bytes:
    return struct.pack("<qqB", seq, time.time_ns(), 16) + g


def read_attachment(raw: bytes) -> tuple[int, int, bytes]:
    assert len(raw) == 33 and raw[16] == 0x10, raw
    seq, ts = struct.unpack_from("<qq", raw)
    return seq, ts, raw[17:]


class RmwObserver:
    """Graph discovery, subscriptions, a Twist publisher and a service client."""

    def __init__(
        self, session: zenoh.Session, domain: int = 0, namespace: str = "/", name: str = "observer"
    ) -> None:
        self.s = session
        self.domain = domain
        self.zid = str(session.zid())
        ns = namespace.replace("/", "%")
        self.prefix = f"@ros2_lv/{domain}/{self.zid}/0"
        self.node_tail = f"%/{ns}/{name}"
        self._next_id = 1
        self._tokens: list[Any] = [
            session.liveliness().declare_token(f"{self.prefix}/0/NN/{self.node_tail}")
        ]
        self._cond = threading.Condition()
        self.graph: dict[str, dict[str, str]] = {}
        self._lv = session.liveliness().declare_subscriber(
            f"@ros2_lv/{domain}/**", self._on_token, history=True
        )
        self._subs: list[Any] = []

    # -- graph -----------------------------------------------------------------------------
    def _on_token(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        parts = key.split("/")
        with self._cond:
            if sample.kind == zenoh.SampleKind.DELETE:
                self.graph.pop(key, None)
            else:
                e = {
                    "zid": parts[2],
                    "nid": parts[3],
                    "id": parts[4],
                    "kind": parts[5],
                    "namespace": parts[7].replace("%", "/"),
                    "node": parts[8],
                }
                if len(parts) >= 13:
                    e.update(
                        topic=parts[9].replace("%", "/"),
                        type=parts[10],
                        hash=parts[11],
                        qos=parts[12],
                    )
                self.graph[key] = e
            self._cond.notify_all()

    def wait_for(
        self, predicate: Callable[[dict[str, dict[str, str]]], bool], timeout: float = 20.0
    ) -> None:
        with self._cond:
            assert self._cond.wait_for(lambda: predicate(self.graph), timeout), self.graph

    def endpoint(self, kind: str, topic: str) -> tuple[str, dict[str, str]] | None:
        with self._cond:
            for k, e in self.graph.items():
                if e["kind"] == kind and e.get("topic") == topic:
                    return k, e
        return None

    def _entity_token(self, kind: str, topic: str, ros_type: str, qos: str) -> str:
        eid = self._next_id
        self._next_id += 1
        topic_chunk = topic.replace("/", "%")
        return (
            f"{self.prefix}/{eid}/{kind}/{self.node_tail}/{topic_chunk}/"
            f"{dds(ros_type)}/{HASH[ros_type]}/{qos}"
        )

    def key(self, topic: str, ros_type: str) -> str:
        return f"{self.domain}/{topic.strip('/')}/{dds(ros_type)}/{HASH[ros_type]}"

    # -- subscriptions ---------------------------------------------------------------------
    def subscribe(
        self, topic: str, ros_type: str, qos: str = "::,10:,:,:,,", transient_local: bool = False
    ):
        """Returns (list of (msg, attachment tuple), condition, closer)."""
        got: list[tuple[Any, tuple[int, int, bytes]]] = []
        cond = threading.Condition()

        def on_sample(sample: zenoh.Sample) -> None:
            att = read_attachment(sample.attachment.to_bytes())
            msg = STORE.deserialize_cdr(sample.payload.to_bytes(), ros_type)
            with cond:
                got.append((msg, att))
                cond.notify_all()

        if transient_local:  # what rmw_zenoh's SubscriptionData::init does for TRANSIENT_LOCAL
            sub = zx.declare_advanced_subscriber(
                self.s,
                self.key(topic, ros_type),
                on_sample,
                history=zx.HistoryConfig(detect_late_publishers=True, max_samples=1),
                recovery=zx.RecoveryConfig(periodic_queries=None, heartbeat=True),
                subscriber_detection=True,
            )
        else:
            sub = self.s.declare_subscriber(self.key(topic, ros_type), on_sample)
        token = self.s.liveliness().declare_token(self._entity_token("MS", topic, ros_type, qos))

        def close() -> None:
            token.undeclare()
            sub.undeclare()

        return got, cond, close

    # -- publishing ------------------------------------------------------------------------
    def publisher(self, topic: str, ros_type: str):
        tok = self._entity_token("MP", topic, ros_type, "::,10:,:,:,,")
        token = self.s.liveliness().declare_token(tok)
        self._tokens.append(token)
        pub = self.s.declare_publisher(self.key(topic, ros_type))
        g = gid(tok)
        seq = [0]

        def put(msg: Any = None, raw: bytes | None = None, att: bytes | bool | None = True) -> None:
            seq[0] += 1
            payload = raw if raw is not None else bytes(STORE.serialize_cdr(msg, ros_type))
            if att is True:
                pub.put(payload, attachment=attachment(seq[0], g))
            elif att:
                pub.put(payload, attachment=att)
            else:
                pub.put(payload)

        return put

    # -- services --------------------------------------------------------------------------
    def call(
        self, service: str, srv_type: str, request: Any, timeout: float = 10.0
    ) -> tuple[Any, tuple[int, int, bytes], bytes, int]:
        tok = self._entity_token("SC", service, srv_type, "::,10:,:,:,,")
        token = self.s.liveliness().declare_token(tok)
        try:
            g = gid(tok)
            seq = 7
            replies = list(
                self.s.get(
                    self.key(service, srv_type),
                    payload=bytes(
                        STORE.serialize_cdr(
                            request, srv_type.replace("/srv/", "/msg/") + "_Request"
                        )
                    ),
                    attachment=attachment(seq, g),
                    target=zenoh.QueryTarget.ALL_COMPLETE,
                    timeout=timeout,
                )
            )
        finally:
            token.undeclare()
        assert replies, f"no reply from {service}"
        r = replies[0]
        assert r.ok is not None, r.err.payload.to_string()
        att = read_attachment(r.ok.attachment.to_bytes())
        reply_type = srv_type.replace("/srv/", "/msg/") + "_Response"
        return STORE.deserialize_cdr(r.ok.payload.to_bytes(), reply_type), att, g, seq

    def close(self) -> None:
        for t in self._tokens:
            t.undeclare()
        self._lv.undeclare()
