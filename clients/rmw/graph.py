"""rmw_zenoh's key expressions: data keys, liveliness tokens, QoS strings (pure functions).

Written from rmw_zenoh_cpp ``src/detail/liveliness_utils.cpp`` (``TopicInfo``, ``Entity``,
``qos_to_keyexpr``, ``mangle_name``) and ``docs/design.md``:

* data key ``<domain>/<topic without leading/trailing '/'>/<dds type>/<type hash>``;
* token ``@ros2_lv/<domain>/<zid>/<nid>/<id>/<KIND>/<enclave>/<ns>/<node>``, endpoints adding
  ``/<topic>/<type>/<hash>/<qos>``,
  with every ``/`` inside a chunk replaced by ``%`` (an empty namespace "/" becomes ``%``);
* QoS ``REL:DUR:HIST,DEPTH:DL_S,DL_NS:LS_S,LS_NS:LIV,LEASE_S,LEASE_NS``, a field empty when it
  equals rmw_zenoh's default profile (reliable, volatile, keep-last 42, infinite, automatic).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from enum import StrEnum

from schemas.keys import ROS_LIVELINESS

ADMIN_SPACE = ROS_LIVELINESS


class Kind(StrEnum):
    NODE = "NN"
    PUBLISHER = "MP"
    SUBSCRIPTION = "MS"
    SERVICE = "SS"
    CLIENT = "SC"


# rmw enum values (rmw/types.h)
RELIABLE, BEST_EFFORT = 1, 2
TRANSIENT_LOCAL, VOLATILE = 1, 2
KEEP_LAST, KEEP_ALL = 1, 2
AUTOMATIC, MANUAL_BY_TOPIC = 1, 3
DEFAULT_DEPTH = 42  # rmw_zenoh's QoS::default_qos()


@dataclass(frozen=True)
class QoS:
    """A ROS QoS profile, as rmw_zenoh writes it in liveliness tokens."""

    reliability: int = RELIABLE
    durability: int = VOLATILE
    history: int = KEEP_LAST
    depth: int = DEFAULT_DEPTH
    # deadline / lifespan / liveliness lease are left at the default (infinite): a field we
    # do not implement must not be advertised.
    liveliness: int = AUTOMATIC

    def keyexpr(self) -> str:
        d = QoS()

        def f(v: int, dv: int) -> str:
            return "" if v == dv else str(v)

        return (
            f"{f(self.reliability, d.reliability)}:{f(self.durability, d.durability)}:"
            f"{f(self.history, d.history)},{f(self.depth, d.depth)}:,:,:"
            f"{f(self.liveliness, d.liveliness)},,"
        )

    @classmethod
    def parse(cls, text: str) -> QoS:
        """The inverse of :meth:`keyexpr` (deadline/lifespan/lease values are ignored)."""
        parts = text.split(":")
        if len(parts) != 6:
            raise ValueError(f"QoS {text!r} has {len(parts)} ':'-fields, rmw_zenoh writes 6")
        hist = parts[2].split(",")
        live = parts[5].split(",")
        if len(hist) != 2 or len(live) != 3 or len(parts[3].split(",")) != 2:
            raise ValueError(f"QoS {text!r} is not in rmw_zenoh's format")
        d = cls()
        try:
            return cls(
                reliability=int(parts[0]) if parts[0] else d.reliability,
                durability=int(parts[1]) if parts[1] else d.durability,
                history=int(hist[0]) if hist[0] else d.history,
                depth=int(hist[1]) if hist[1] else d.depth,
                liveliness=int(live[0]) if live[0] else d.liveliness,
            )
        except ValueError as exc:
            raise ValueError(f"QoS {text!r} has a non-numeric field") from exc


SENSOR_QOS = QoS(reliability=BEST_EFFORT, depth=5)  # rclcpp SensorDataQoS
LATCHED_QOS = QoS(durability=TRANSIENT_LOCAL, depth=1)  # robot_state_publisher's description
DEFAULT_QOS = QoS(depth=10)  # what rclpy/rclcpp nodes usually ask for
SERVICE_QOS = QoS(depth=10)  # rmw_qos_profile_services_default: reliable, volatile, keep-last 10


def mangle(name: str) -> str:
    return name.replace("/", "%")


def demangle(name: str) -> str:
    return name.replace("%", "/")


def strip_slashes(name: str) -> str:
    """rmw_zenoh's ``strip_slashes``: one leading and one trailing '/' go."""
    if name.startswith("/"):
        name = name[1:]
    if name.endswith("/"):
        name = name[:-1]
    return name


_NAME = re.compile(r"^/([A-Za-z_][A-Za-z0-9_]*)(/[A-Za-z_][A-Za-z0-9_]*)*$|^/$")


def check_namespace(ns: str) -> str:
    """A ROS namespace: absolute, tokens of letters, digits and '_' (not starting with a digit)."""
    if not _NAME.match(ns):
        raise ValueError(
            f"namespace {ns!r} is not a ROS namespace: write it like /op1 (letters, digits, '_')"
        )
    return ns


def resolve(namespace: str, name: str) -> str:
    """Fully qualified name of a relative topic/service in a node namespace."""
    if name.startswith("/"):
        return name
    return f"{namespace.rstrip('/')}/{name}"


def data_key(domain: int, topic: str, dds_type: str, type_hash: str) -> str:
    return f"{domain}/{strip_slashes(topic)}/{dds_type}/{type_hash}"


@dataclass(frozen=True)
class Node:
    """A ROS node in rmw_zenoh's graph: its domain, session, id, namespace and name."""

    domain: int
    zid: str
    nid: int
    namespace: str
    name: str
    enclave: str = "/"

    def token(self) -> str:
        return self._token(self.nid, Kind.NODE)

    def entity_token(
        self, eid: int, kind: Kind, topic: str, dds_type: str, type_hash: str, qos: QoS
    ) -> str:
        return self._token(
            eid, kind, mangle(topic), mangle(dds_type), mangle(type_hash), qos.keyexpr()
        )

    def _token(self, eid: int, kind: Kind, *rest: str) -> str:
        # The node's own token is an entity token whose entity id is the node id.
        return "/".join(
            (
                ADMIN_SPACE,
                str(self.domain),
                self.zid,
                str(self.nid),
                str(eid),
                kind.value,
                mangle(self.enclave),
                mangle(self.namespace),
                mangle(self.name),
                *rest,
            )
        )


@dataclass(frozen=True)
class Entity:
    """A parsed liveliness token (as rmw_zenoh's ``Entity::make(keyexpr)`` reads it)."""

    domain: int
    zid: str
    nid: str
    id: str
    kind: Kind
    enclave: str
    namespace: str
    node: str
    topic: str | None = None
    dds_type: str | None = None
    type_hash: str | None = None
    qos: QoS | None = None


def parse_token(key: str) -> Entity:
    parts = key.split("/")
    if len(parts) < 9 or any(not p for p in parts) or parts[0] != ADMIN_SPACE:
        raise ValueError(f"{key!r} is not an rmw_zenoh liveliness token")
    try:
        kind = Kind(parts[5])
    except ValueError:
        raise ValueError(f"{key!r}: unknown entity kind {parts[5]!r}") from None
    node = Entity(
        domain=int(parts[1]),
        zid=parts[2],
        nid=parts[3],
        id=parts[4],
        kind=kind,
        enclave=demangle(parts[6]),
        namespace=demangle(parts[7]),
        node=demangle(parts[8]),
    )
    if kind is Kind.NODE:
        return node
    if len(parts) < 13:
        raise ValueError(f"{key!r}: an endpoint token needs topic, type, hash and QoS")
    return replace(
        node,
        topic=demangle(parts[9]),
        dds_type=demangle(parts[10]),
        type_hash=demangle(parts[11]),
        qos=QoS.parse(parts[12]),
    )


def graph_selector(domain: int) -> str:
    """What to subscribe or query to see one domain's ROS graph."""
    return f"{ADMIN_SPACE}/{domain}/**"
