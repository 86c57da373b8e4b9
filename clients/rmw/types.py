"""ROS 2 message types, CDR and type hashes, from rosbags (no ROS install needed).

One typestore (Jazzy) for every message the adapter speaks. Service types are added the way
rosidl defines them (``rosidl_generator_type_description``): ``<Name>_Request``,
``<Name>_Response``, ``<Name>_Event`` (``service_msgs/ServiceEventInfo info``, ``request[<=1]``,
``response[<=1]``) and the service itself as a type with ``request_message``,
``response_message`` and ``event_message`` fields, whose RIHS01 hash is the service's hash.
An empty request (std_srvs/Trigger) carries rosidl's ``uint8 structure_needs_at_least_one_member``.
"""

from __future__ import annotations

from functools import cache
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg
from rosbags.typesys import get_typestore as _get_typestore
from rosbags.typesys.base import Nodetype

from schemas.errors import ProtocolError

# ros type name -> (request fields, response fields) in .msg syntax
SERVICES: dict[str, tuple[str, str]] = {
    "std_srvs/srv/Trigger": (
        "uint8 structure_needs_at_least_one_member",
        "bool success\nstring message",
    ),
    "std_srvs/srv/SetBool": ("bool data", "bool success\nstring message"),
}


_EVENT_INFO = "service_msgs/msg/ServiceEventInfo"


class CdrError(ProtocolError, ValueError):
    """CDR bytes that do not decode as the message type says."""


def _fields(msg_text: str) -> list[Any]:
    return get_types_from_msg(msg_text, "x/msg/X")["x/msg/X"][1]


@cache
def typestore() -> Any:
    store = _get_typestore(Stores.ROS2_JAZZY)
    add: dict[str, Any] = {}
    for srv, (req, rep) in SERVICES.items():
        if srv in store.fielddefs:
            continue
        # rosbags' .msg parser files everything under <pkg>/msg/: build the srv names directly.
        request, response, event = f"{srv}_Request", f"{srv}_Response", f"{srv}_Event"
        add[request] = ([], _fields(req))
        add[response] = ([], _fields(rep))
        add[event] = (
            [],
            [
                ("info", (Nodetype.NAME, "service_msgs/msg/ServiceEventInfo")),
                ("request", (Nodetype.SEQUENCE, ((Nodetype.NAME, request), 1))),
                ("response", (Nodetype.SEQUENCE, ((Nodetype.NAME, response), 1))),
            ],
        )
        add[srv] = (
            [],
            [
                ("request_message", (Nodetype.NAME, request)),
                ("response_message", (Nodetype.NAME, response)),
                ("event_message", (Nodetype.NAME, event)),
            ],
        )
    if add:
        store.register(add)
    # rosidl reads .msg ``char`` as IDL ``uint8`` (rosidl_adapter), so ServiceEventInfo's
    # ``char[16] client_gid`` is a uint8 array in the type description; rosbags hashes it as
    # FIELD_TYPE_CHAR, which would give every service a wrong hash. Same bytes on the wire.
    consts, fields = store.fielddefs[_EVENT_INFO]
    store.fielddefs[_EVENT_INFO] = (
        consts,
        [
            (n, (Nodetype.ARRAY, ((Nodetype.BASE, ("uint8", 0)), t[1][1])))
            if t[0] == Nodetype.ARRAY and t[1][0] == (Nodetype.BASE, ("char", 0))
            else (n, t)
            for n, t in fields
        ],
    )
    return store


def msg_class(ros_type: str) -> Any:
    return typestore().types[ros_type]


def dds_type(ros_type: str) -> str:
    """``sensor_msgs/msg/JointState`` → ``sensor_msgs::msg::dds_::JointState_``."""
    pkg, kind, name = ros_type.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


@cache
def type_hash(ros_type: str) -> str:
    """``RIHS01_<64 hex>`` as rosidl computes it."""
    return typestore().hash_rihs01(ros_type)


def encode(msg: Any, ros_type: str) -> bytes:
    return bytes(typestore().serialize_cdr(msg, ros_type))


def decode(raw: bytes, ros_type: str) -> Any:
    """CDR bytes to a message; any malformation becomes :class:`CdrError` naming the type."""
    if len(raw) < 4 or raw[0] != 0 or raw[1] not in (0, 1):
        raise CdrError(f"{ros_type}: not a CDR payload (bad 4-byte encapsulation header)")
    try:
        return typestore().deserialize_cdr(raw, ros_type)
    except Exception as exc:  # rosbags raises assorted errors on truncated or bad data
        raise CdrError(f"{ros_type}: malformed CDR ({type(exc).__name__}: {exc})") from exc
