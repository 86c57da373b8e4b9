"""The ``ros2`` recording profile: a ROS 2 bag in rosbag2's MCAP storage layout.

What the ROS 2 adapter (``darwin ros2``) publishes, made from the daemon's own publications so
no adapter needs to run: ``<ns>/joint_states`` and ``<ns>/tf`` from ``joints``, ``<ns>/imu/data``
from ``imu``, ``<ns>/diagnostics`` from ``status`` (with the latest joints), ``odom → base_link``
on ``<ns>/tf`` from ``world``, ``<ns>/camera/image_raw/compressed`` from ``camera``, and at the
start of every file (segment) the latched ``<ns>/robot_description`` and ``<ns>/tf_static``.
Every conversion is :mod:`clients.rmw.convert` and every byte of CDR :mod:`clients.rmw.types`.

Layout, as rosbag2_storage_mcap writes it: header profile ``ros2``; one schema per type named
``pkg/msg/Type`` with encoding ``ros2msg`` and the complete .msg text (the type, then each
dependency after a line of 80 ``=`` and ``MSG: pkg/Type``: rosbags' ``generate_msgdef``); one
channel per ROS topic with message encoding ``cdr`` and the metadata ``offered_qos_profiles``
(YAML, rosbag2 ≥ 9 spelling) and ``topic_type_hash`` (RIHS01).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from functools import cache
from types import ModuleType
from typing import Any

import zenoh

from clients.recording.profile import DARWIN, ChannelSpec, SchemaSpec
from config.body import default_body
from schemas.body import Body
from schemas.errors import ClientError, DarwinError
from schemas.keys import Keys
from schemas.messages import CameraFrame, Imu, Joints, Status, World
from schemas.urdf import body_from_config_reply, to_urdf

log = logging.getLogger(__name__)

# darwin topic → the ROS topics (relative to the namespace) and types it becomes
ROS_TOPICS: dict[str, tuple[tuple[str, str], ...]] = {
    "joints": (("joint_states", "sensor_msgs/msg/JointState"), ("tf", "tf2_msgs/msg/TFMessage")),
    "imu": (("imu/data", "sensor_msgs/msg/Imu"),),
    "status": (("diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),),
    "world": (("tf", "tf2_msgs/msg/TFMessage"),),
    "camera": (("camera/image_raw/compressed", "sensor_msgs/msg/CompressedImage"),),
}
LATCHED = (
    ("robot_description", "std_msgs/msg/String"),
    ("tf_static", "tf2_msgs/msg/TFMessage"),
)
SENSOR = {"imu/data", "camera/image_raw/compressed"}  # best effort, as the adapter offers them

@cache
def _ros() -> tuple[ModuleType, ModuleType]:
    """The rmw wire library's convert and types, imported on first use: rosbags is the ros2
    extra."""
    try:
        from clients.rmw import convert, types
    except ImportError as exc:
        raise ClientError(
            f"the ros2 recording profile needs the ros2 extra ({exc.name} is missing): "
            "pip install -e '.[ros2]' in the project's clone"
        ) from exc
    return convert, types


def encode(msg: Any, ros_type: str) -> bytes:
    return _ros()[1].encode(msg, ros_type)


def msg_class(ros_type: str) -> Any:
    return _ros()[1].msg_class(ros_type)


_FOREVER = "{sec: 9223372036, nsec: 854775807}"


def qos_yaml(reliability: str, durability: str, depth: int) -> str:
    """One offered QoS profile in rosbag2's YAML (metadata version ≥ 9: policy names)."""
    return (
        f"- history: keep_last\n  depth: {depth}\n  reliability: {reliability}\n"
        f"  durability: {durability}\n  deadline: {_FOREVER}\n  lifespan: {_FOREVER}\n"
        f"  liveliness: automatic\n  liveliness_lease_duration: {_FOREVER}\n"
        "  avoid_ros_namespace_conventions: false"
    )


@cache
def ros_schema(ros_type: str) -> SchemaSpec:
    text, _ = _ros()[1].typestore().generate_msgdef(ros_type, ros_version=2)
    return SchemaSpec(ros_type, "ros2msg", text.encode())


def ros_channel(
    namespace: str, name: str, ros_type: str, encoder: Callable[..., bytes | None]
) -> ChannelSpec:
    latched = (name, ros_type) in LATCHED
    qos = qos_yaml(
        "best_effort" if name in SENSOR else "reliable",
        "transient_local" if latched else "volatile",
        1 if latched else 10,
    )
    return ChannelSpec(
        f"{namespace}/{name}",
        "cdr",
        ros_schema(ros_type),
        encoder,
        {"offered_qos_profiles": qos, "topic_type_hash": _ros()[1].type_hash(ros_type)},
    )


def body_for(session: zenoh.Session, keys: Keys) -> Body:
    """The daemon's body (its config reply: its own joint limits), else the local config's."""
    from clients.commander import Commander

    try:
        # Closed at once: its liveliness token must not outlive the question.
        with Commander(robot=keys.robot, session=session, name="recorder", timeout=2.0) as c:
            cfg = c.config()
        return body_from_config_reply(cfg)
    except DarwinError as exc:
        log.debug("config query: %s", exc)
        log.warning(
            "robot %r did not answer `config`: the bag describes the local robot config's body",
            keys.robot,
        )
        return default_body()


class Ros2Profile:
    """ROS 2 bag layout; :meth:`bind` makes the per-recording instance (body, filter state)."""

    name = "ros2"
    mcap_profile = "ros2"
    topics = tuple(ROS_TOPICS)
    default_topics = tuple(t for t in DARWIN.default_topics if t in ROS_TOPICS)

    def __init__(self, body: Body | None = None, namespace: str = "") -> None:
        self.body = body
        self.namespace = namespace
        self.names_by_id = (
            {j.servo_id: j.name for j in body.servo_joints()} if body is not None else {}
        )
        self._tilt: Any = None  # the IMU filter, made by bind()
        self._joints: Joints | None = None

    def bind(self, session: zenoh.Session, keys: Keys) -> Ros2Profile:
        bound = Ros2Profile(body_for(session, keys), f"/{keys.robot}")
        bound._tilt = _ros()[0].TiltFilter()
        return bound

    def key(self, keys: Keys, topic: str) -> str:
        return DARWIN.key(keys, topic)

    def decode(self, topic: str, payload: bytes) -> dict[str, Any] | None:
        return DARWIN.decode(topic, payload)

    def publish_ns(self, decoded: dict[str, Any] | None, log_ns: int) -> int:
        return DARWIN.publish_ns(decoded, log_ns)

    def _body(self) -> Body:
        if self.body is None:
            raise RuntimeError("the ros2 profile is used unbound: call bind(session, keys)")
        return self.body

    # -- encoders: decoded darwin message → CDR ------------------------------------------------
    def _joint_states(self, _p: bytes, d: dict[str, Any] | None) -> bytes | None:
        if d is None:
            return None
        self._joints = Joints.from_dict(d)
        msg = _ros()[0].joint_state(self._joints, self.names_by_id)
        return encode(msg, "sensor_msgs/msg/JointState")

    def _tf_joints(self, _p: bytes, d: dict[str, Any] | None) -> bytes | None:
        if d is None:
            return None
        j = Joints.from_dict(d)
        positions = dict(zip(j.id, j.position, strict=True))
        msg = _ros()[0].tf_joints(self._body(), positions, j.stamp)
        return encode(msg, "tf2_msgs/msg/TFMessage")

    def _imu(self, _p: bytes, d: dict[str, Any] | None) -> bytes | None:
        if d is None:
            return None
        return encode(_ros()[0].imu(Imu.from_dict(d), self._tilt), "sensor_msgs/msg/Imu")

    def _diagnostics(self, _p: bytes, d: dict[str, Any] | None) -> bytes | None:
        if d is None:
            return None
        st = Status.from_dict(d)
        msg = _ros()[0].diagnostics(self._joints, st, self.names_by_id, st.stamp)
        return encode(msg, "diagnostic_msgs/msg/DiagnosticArray")

    def _tf_odom(self, _p: bytes, d: dict[str, Any] | None) -> bytes | None:
        if d is None:
            return None
        return encode(_ros()[0].tf_odom(World.from_dict(d)), "tf2_msgs/msg/TFMessage")

    def _camera(self, _p: bytes, d: dict[str, Any] | None) -> bytes | None:
        if d is None:
            return None
        c = CameraFrame.from_dict(d)
        msg = _ros()[0].compressed_image(c.jpeg, c.stamp)
        return encode(msg, "sensor_msgs/msg/CompressedImage")

    def channels(self, topic: str, key: str, robot: str) -> tuple[ChannelSpec, ...]:
        encoders: dict[str, tuple[Callable[..., bytes | None], ...]] = {
            "joints": (self._joint_states, self._tf_joints),
            "imu": (self._imu,),
            "status": (self._diagnostics,),
            "world": (self._tf_odom,),
            "camera": (self._camera,),
        }
        return tuple(
            ros_channel(self.namespace, name, ros_type, enc)
            for (name, ros_type), enc in zip(ROS_TOPICS[topic], encoders[topic], strict=True)
        )

    def latched(self) -> tuple[tuple[ChannelSpec, bytes], ...]:
        """The transient-local topics, written at the start of every file."""
        body = self._body()
        description = encode(msg_class("std_msgs/msg/String")(data=to_urdf(body)), LATCHED[0][1])
        static = encode(_ros()[0].tf_joints(body, {}, time.time(), moving=False), LATCHED[1][1])
        return tuple(
            (ros_channel(self.namespace, name, ros_type, lambda p, d: p), data)
            for (name, ros_type), data in zip(LATCHED, (description, static), strict=True)
        )


ROS2 = Ros2Profile()
