"""The Foxglove server: the robot's publications as channels, Foxglove's requests as commands.

A client of the key space like the TUI: it reads through a :class:`clients.robot.Robot` and
commands through per-Foxglove-client Commanders (see :mod:`clients.foxglove.control`).
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
import time
from typing import Any

import foxglove
from foxglove import Channel, Schema
from foxglove.channels import (
    CompressedImageChannel,
    FrameTransformsChannel,
    ImageAnnotationsChannel,
    LogChannel,
    SceneUpdateChannel,
)
from foxglove.messages import Color, Pose, Quaternion, SceneEntity, SceneUpdate, SpherePrimitive
from foxglove.messages import Vector3 as FVector3
from foxglove.websocket import (
    Capability,
    ChannelView,
    Client,
    ClientChannel,
    MessageSchema,
    Parameter,
    Service,
    ServiceRequest,
    ServiceSchema,
    StatusLevel,
    WebSocketServer,
)

from clients.foxglove import convert, frames
from clients.foxglove.control import SERVICES, Commanders, Teleop, call_service
from clients.foxglove.params import WalkParameters
from clients.foxglove.presence import Presence
from clients.foxglove.urdf import robot_body
from clients.robot import Robot, Subscription
from schemas.errors import AdapterInputError
from schemas.messages import BallDetection, CameraFrame, Event, Imu, Joints, Status, World
from schemas.urdf import to_urdf

log = logging.getLogger(__name__)

BALL_DIAMETER = 0.07  # drawing only: the sphere the 3D panel shows at the ball's frame
URDF_PERIOD = 2.0  # s between republications of the URDF, for panels that open late


class Bridge:
    """Owns the channels, the server and the robot's subscriptions; ``close()`` ends all."""

    def __init__(
        self, robot: Robot, host: str = "127.0.0.1", port: int = 8765, tf_rate: float = 0.0
    ) -> None:
        self.robot = robot
        self.tf_period = 1.0 / tf_rate if tf_rate > 0 else 0.0
        self._last_tf = 0.0
        self._height = 0.0
        self._world_seen = False
        self._lock = threading.Lock()
        self._camera_clients: set[int] = set()
        self._camera_sub: Subscription | None = None
        self._client_refs: dict[int, set[tuple[str, int]]] = {}
        self.ctx = foxglove.Context()
        c = self.ctx
        self.ch_tf = FrameTransformsChannel("/tf", context=c)
        self.ch_joints = Channel("/joints", schema=_schema("darwin.Joints"), context=c)
        self.ch_imu = Channel("/imu", schema=_schema("darwin.Imu"), context=c)
        self.ch_status = Channel("/status", schema=_schema("darwin.Status"), context=c)
        self.ch_loop = Channel("/loop", schema=_schema("darwin.Loop"), context=c)
        self._loop_overloaded = False  # the last status.loop.overloaded seen (warned on rising)
        self.ch_world = Channel("/world", schema=_schema("darwin.World"), context=c)
        self.ch_events = LogChannel("/events", context=c)
        self.ch_camera = CompressedImageChannel("/camera/image", context=c)
        self.ch_ball = ImageAnnotationsChannel("/camera/ball", context=c)
        self.ch_scene = SceneUpdateChannel("/scene", context=c)
        self.body = robot_body(robot)
        self.urdf = to_urdf(self.body)
        # Foxglove's URDF layer reads a topic of std_msgs/String-shaped messages.
        self.ch_urdf = Channel(
            "/robot_description",
            schema={
                "title": "std_msgs/String",
                "type": "object",
                "properties": {"data": {"type": "string"}},
            },
            context=c,
        )
        self.commanders = Commanders(robot)
        self.teleop = Teleop(self.commanders, self.warn)
        self.params = WalkParameters(self.commanders, robot, self.warn)
        try:
            self.server: WebSocketServer = foxglove.start_server(
                name=f"darwin {robot.target.robot}",
                host=host,
                port=port,
                capabilities=[
                    Capability.ClientPublish,
                    Capability.Parameters,
                    Capability.Services,
                ],
                supported_encodings=["json"],
                # The SDK calls only the callbacks a listener defines; its Protocol lists all.
                server_listener=_Listener(self),  # type: ignore[arg-type]
                services=[self._service(name) for name in SERVICES],
                context=c,
            )
        except BaseException:
            self.teleop.close()
            self.commanders.close()
            raise
        self._subs = [
            robot.subscribe("joints", self._on_joints),
            robot.subscribe("imu", self._on_imu),
            robot.subscribe("status", self._on_status),
            robot.subscribe("events", self._on_event),
            robot.subscribe("world", self._on_world),
            robot.subscribe("vision", self._on_ball),
        ]
        self.presence = Presence(robot, self.server)
        self._stop = threading.Event()
        self._urdf_now = threading.Event()
        self._urdf_thread = threading.Thread(target=self._urdf_loop, daemon=True)
        self._urdf_thread.start()

    @property
    def port(self) -> int:
        return self.server.port

    def close(self) -> None:
        self._stop.set()
        self._urdf_now.set()
        self.presence.close()
        for sub in self._subs:
            with contextlib.suppress(Exception):
                sub.close()
        with self._lock:
            cam, self._camera_sub = self._camera_sub, None
        if cam is not None:
            cam.close()
        self.teleop.close()
        self.commanders.close()
        self.server.stop()

    def warn(self, message: str) -> None:
        log.warning("%s", message)
        self.server.publish_status(message, StatusLevel.Warning)

    # -- services ----------------------------------------------------------------------------
    def _service(self, name: str) -> Service:
        _handler, req_schema = SERVICES[name]
        schema = ServiceSchema(
            f"darwin{name}",
            request=MessageSchema(
                encoding="json",
                schema=Schema(
                    name=f"darwin{name}.Request",
                    encoding="jsonschema",
                    data=json.dumps(req_schema).encode(),
                ),
            ),
            response=MessageSchema(
                encoding="json",
                schema=Schema(
                    name=f"darwin{name}.Response",
                    encoding="jsonschema",
                    data=json.dumps({"type": "object"}).encode(),
                ),
            ),
        )

        def handler(req: ServiceRequest) -> bytes:
            try:
                return call_service(self.commanders, name, req.client_id, req.payload)
            except AdapterInputError as exc:
                raise ValueError(str(exc)) from None

        return Service(name, schema=schema, handler=handler)

    # -- publications --------------------------------------------------------------------------
    def _on_joints(self, msg: Joints) -> None:
        t = convert.nanos(msg.stamp)
        if self.ch_joints.has_sinks():
            self.ch_joints.log(convert.joints_json(msg), log_time=t)
        if not self.ch_tf.has_sinks():
            return
        now = time.monotonic()
        if self.tf_period and now - self._last_tf < self.tf_period:
            return
        self._last_tf = now
        pos = frames.positions_by_id(msg.id, msg.position)
        tree = frames.body_transforms(self.body, pos)
        self._height = float(tree[-1][2][2, 3])
        if self._world_seen:
            tree = tree[:-1]  # the world pose gives field → base_link
        self.ch_tf.log(convert.transforms(tree, msg.stamp), log_time=t)

    def _on_imu(self, msg: Imu) -> None:
        if self.ch_imu.has_sinks():
            self.ch_imu.log(convert.plain(msg), log_time=convert.nanos(msg.stamp))

    def _on_status(self, msg: Status) -> None:
        t = convert.nanos(msg.stamp)
        if self.ch_status.has_sinks():
            self.ch_status.log(convert.plain(msg), log_time=t)
        if self.ch_loop.has_sinks():
            self.ch_loop.log(convert.loop_json(msg), log_time=t)
        overloaded = bool((msg.loop or {}).get("overloaded", False))
        if overloaded != self._loop_overloaded:
            self._loop_overloaded = overloaded
            if overloaded:
                pct = (msg.loop or {}).get("overrun_pct", 0.0)
                self.warn(f"robot loop OVERLOADED: {pct:.0f} % of ticks overran")

    def _on_event(self, msg: Event) -> None:
        self.ch_events.log(convert.log_entry(msg), log_time=convert.nanos(msg.stamp))

    def _on_world(self, msg: World) -> None:
        self._world_seen = True
        t = convert.nanos(msg.stamp)
        if self.ch_world.has_sinks():
            self.ch_world.log(convert.plain(msg), log_time=t)
        if self.ch_tf.has_sinks():
            tree = frames.world_transforms(msg, self._height)
            self.ch_tf.log(convert.transforms(tree, msg.stamp), log_time=t)
        if msg.ball and self.ch_scene.has_sinks():
            self.ch_scene.log(_ball_scene(msg), log_time=t)

    def _on_ball(self, msg: BallDetection) -> None:
        if self.ch_ball.has_sinks():
            self.ch_ball.log(convert.ball_annotations(msg), log_time=convert.nanos(msg.stamp))

    def _on_camera(self, msg: CameraFrame) -> None:
        self.ch_camera.log(convert.image(msg), log_time=convert.nanos(msg.stamp))

    def _urdf_loop(self) -> None:
        while not self._stop.is_set():
            if self.ch_urdf.has_sinks():
                self.ch_urdf.log({"data": self.urdf})
            self._urdf_now.wait(URDF_PERIOD)
            self._urdf_now.clear()

    # -- who watches what -----------------------------------------------------------------------
    def subscribed(self, client: Client, channel: ChannelView) -> None:
        self._ref(client.id, ("sub", channel.id), True)
        if channel.id == self.ch_urdf.id():
            self._urdf_now.set()  # published from its thread, never inside the SDK's callback
        if channel.id != self.ch_camera.id():
            return
        with self._lock:
            self._camera_clients.add(client.id)
            if self._camera_sub is None:
                # The daemon captures only while someone subscribes to its camera key.
                self._camera_sub = self.robot.subscribe("camera", self._on_camera)

    def unsubscribed(self, client: Client, channel: ChannelView) -> None:
        if channel.id == self.ch_camera.id():
            with self._lock:
                self._camera_clients.discard(client.id)
                sub = self._camera_sub if not self._camera_clients else None
                if sub is not None:
                    self._camera_sub = None
            if sub is not None:
                sub.close()
        self._ref(client.id, ("sub", channel.id), False)

    def _ref(self, client_id: int, ref: tuple[str, int], add: bool) -> None:
        """Track what each Foxglove client holds: the SDK reports a disconnect only as
        unsubscribes and unadvertises, so a client left holding nothing has gone, and its
        Commander (and with it its lease, safely stopped) goes too."""
        with self._lock:
            refs = self._client_refs.setdefault(client_id, set())
            if add:
                refs.add(ref)
                return
            refs.discard(ref)
            gone = not refs
            if gone:
                del self._client_refs[client_id]
        if gone:
            self.teleop.forget(client_id)
            self.commanders.drop(client_id)


class _Listener:
    """The SDK's server listener: every callback is guarded so a bad request is reported to
    the clients and never takes the server down."""

    def __init__(self, bridge: Bridge) -> None:
        self.b = bridge
        self._client_channels: dict[tuple[int, int], ClientChannel] = {}

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self._guard("subscribe", self.b.subscribed, client, channel)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        self._guard("unsubscribe", self.b.unsubscribed, client, channel)

    def on_client_advertise(self, client: Client, channel: ClientChannel) -> None:
        if channel.encoding != "json":
            self.b.warn(
                f"client channel {channel.topic!r}: encoding {channel.encoding!r} is not "
                "supported; publish JSON (Teleop: geometry_msgs/Twist)"
            )
            return
        self._client_channels[(client.id, channel.id)] = channel
        self.b._ref(client.id, ("adv", channel.id), True)

    def on_client_unadvertise(self, client: Client, client_channel_id: int) -> None:
        if self._client_channels.pop((client.id, client_channel_id), None) is not None:
            self.b.teleop.forget(client.id)
            self.b._ref(client.id, ("adv", client_channel_id), False)

    def on_message_data(self, client: Client, client_channel_id: int, data: bytes) -> None:
        channel = self._client_channels.get((client.id, client_channel_id))
        if channel is None:
            self.b.warn(f"message on unknown client channel {client_channel_id}: ignored")
            return
        self._guard("teleop", self.b.teleop.on_message, client.id, data)

    def on_get_parameters(
        self, client: Client, param_names: list[str], request_id: str | None = None
    ) -> list[Parameter]:
        return self._guard("get parameters", self.b.params.get, param_names) or []

    def on_set_parameters(
        self, client: Client, parameters: list[Parameter], request_id: str | None = None
    ) -> list[Parameter]:
        return self._guard("set parameters", self.b.params.set, client.id, parameters) or []

    def _guard(self, what: str, fn: Any, *args: Any) -> Any:
        try:
            return fn(*args)
        except Exception as exc:
            self.b.warn(f"{what}: {exc}")
            return None


def _schema(title: str) -> dict[str, Any]:
    return {"title": title, "type": "object"}


def _ball_scene(world: World) -> SceneUpdate:
    size = FVector3(x=BALL_DIAMETER, y=BALL_DIAMETER, z=BALL_DIAMETER)
    pose = Pose(
        position=FVector3(x=0.0, y=0.0, z=BALL_DIAMETER / 2),
        orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
    )
    sphere = SpherePrimitive(pose=pose, size=size, color=Color(r=0.9, g=0.1, b=0.1, a=1.0))
    entity = SceneEntity(
        timestamp=convert.stamp_of(world.stamp), frame_id=frames.BALL, id="ball", spheres=[sphere]
    )
    return SceneUpdate(entities=[entity])
