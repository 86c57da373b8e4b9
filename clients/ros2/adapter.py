"""``darwin ros2``: the robot as a native ROS 2 node over rmw_zenoh's wire format.

A client of the key space like the TUI: state comes from the daemon's publications through a
:class:`clients.robot.Robot`, every command goes through the arbiter with that Robot's lease.
Zenoh callbacks only hand work over: one publishing thread converts and puts, one command thread
talks to the arbiter, so neither a slow arbiter nor a burst of ROS traffic blocks Zenoh. This
module is the publishing side; the commands are :mod:`clients.ros2.commands`.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from dataclasses import dataclass
from typing import Any

import zenoh

from clients.rmw import convert, graph
from clients.rmw.types import msg_class
from clients.robot import Robot
from clients.ros2.commands import RosCommandPort
from clients.ros2.node import GraphWatch, RosNode
from schemas.body import Body
from schemas.messages import CameraFrame, Imu, Joints, World
from schemas.urdf import body_from_config_reply, to_urdf

log = logging.getLogger("darwin.ros2")

CAMERA_TOPIC = "camera/image_raw/compressed"


@dataclass
class Options:
    """How the ROS 2 node runs: its domain, namespace and name, joint rate and lease timeout."""

    domain: int = 0
    namespace: str = "/op1"
    node_name: str = "darwin"
    joint_rate: float | None = None  # Hz; None = every tick
    lease_idle: float = 10.0  # s without a ROS command → release an automatically taken lease


class Adapter:
    def __init__(self, robot: Robot, ros_session: zenoh.Session, options: Options) -> None:
        self.robot = robot
        self.options = options
        self.session = ros_session
        cfg = robot.config()
        self.body: Body = body_from_config_reply(cfg)
        self.names_by_id = {j.servo: j.name for j in self.body.servo_joints()}
        self.limits = {
            j.name: convert.Limit(j.servo, j.lower, j.upper) for j in self.body.servo_joints()
        }
        self.node = RosNode(ros_session, options.domain, options.namespace, options.node_name)
        self._stop = threading.Event()
        self._errors: list[str] = []
        self.stats = {"joint_states": 0, "imu": 0, "camera": 0, "rejected": 0}
        self._make_publishers()
        # Latest input per topic, coalesced: the publisher thread always sends the newest.
        self._slots: dict[str, Any] = {}
        self._cond = threading.Condition()
        self._last_joint_pub = 0.0
        self._tilt = convert.TiltFilter()
        self._camera_sub: Any = None
        self._camera_lock = threading.Lock()
        self.commands = RosCommandPort(
            robot, self.node, self.limits, options.lease_idle, self._stop, self.stats,
            self._report,
        )
        self._threads = [
            threading.Thread(target=self._publish_loop, name="ros2-publish", daemon=True),
            threading.Thread(target=self.commands.run, name="ros2-commands", daemon=True),
            threading.Thread(target=self._timer_loop, name="ros2-timers", daemon=True),
        ]
        self._subs = [
            robot.subscribe("joints", lambda m: self._put("joints", m)),
            robot.subscribe("imu", lambda m: self._put("imu", m)),
            robot.subscribe("world", lambda m: self._put("world", m)),
        ]
        self.graph = GraphWatch(ros_session, options.domain, self._graph_changed)
        self._update_camera()
        for t in self._threads:
            t.start()

    # -- ROS entities ----------------------------------------------------------------------
    def _make_publishers(self) -> None:
        n = self.node
        self.pub_joints = n.publisher(
            "joint_states", "sensor_msgs/msg/JointState", graph.DEFAULT_QOS
        )
        self.pub_imu = n.publisher("imu/data", "sensor_msgs/msg/Imu", graph.SENSOR_QOS)
        self.pub_camera = n.publisher(
            CAMERA_TOPIC, "sensor_msgs/msg/CompressedImage", graph.SENSOR_QOS
        )
        self.pub_description = n.publisher(
            "robot_description", "std_msgs/msg/String", graph.LATCHED_QOS
        )
        self.pub_tf = n.publisher("tf", "tf2_msgs/msg/TFMessage", graph.QoS(depth=100))
        self.pub_tf_static = n.publisher("tf_static", "tf2_msgs/msg/TFMessage", graph.LATCHED_QOS)
        self.pub_diag = n.publisher(
            "diagnostics", "diagnostic_msgs/msg/DiagnosticArray", graph.DEFAULT_QOS
        )
        self.pub_description.publish(msg_class("std_msgs/msg/String")(data=to_urdf(self.body)))
        self.pub_tf_static.publish(convert.tf_joints(self.body, {}, time.time(), moving=False))

    # -- publishing ------------------------------------------------------------------------
    def _put(self, topic: str, msg: Any) -> None:
        with self._cond:
            self._slots[topic] = msg
            self._cond.notify()

    def _publish_loop(self) -> None:
        while not self._stop.is_set():
            with self._cond:
                while not self._slots and not self._stop.is_set():
                    self._cond.wait(0.5)
                slots, self._slots = self._slots, {}
            try:
                self._publish(slots)
            except Exception:
                log.exception("publishing to ROS failed")

    def _publish(self, slots: dict[str, Any]) -> None:
        joints: Joints | None = slots.get("joints")
        if joints is not None:
            rate = self.options.joint_rate
            now = time.monotonic()
            if rate is None or now - self._last_joint_pub >= 1.0 / rate - 1e-4:
                self._last_joint_pub = now
                self.pub_joints.publish(convert.joint_state(joints, self.names_by_id))
                positions = dict(zip(joints.id, joints.position, strict=True))
                self.pub_tf.publish(convert.tf_joints(self.body, positions, joints.stamp))
                self.stats["joint_states"] += 1
        m: Imu | None = slots.get("imu")
        if m is not None:
            self.pub_imu.publish(convert.imu(m, self._tilt))
            self.stats["imu"] += 1
        w: World | None = slots.get("world")
        if w is not None:
            self.pub_tf.publish(convert.tf_odom(w))
        c: CameraFrame | None = slots.get("camera")
        if c is not None:
            self.pub_camera.publish(convert.compressed_image(c.jpeg, c.stamp))
            self.stats["camera"] += 1

    def _graph_changed(self) -> None:
        # Zenoh's liveliness thread: decide here, (un)subscribe in a short-lived thread.
        threading.Thread(target=self._update_camera, daemon=True).start()

    def _update_camera(self) -> None:
        watch = getattr(self, "graph", None)  # tokens may arrive while __init__ still runs
        if watch is None:
            return
        wanted = watch.subscribers(self.pub_camera.topic) > 0 and not self._stop.is_set()
        with self._camera_lock:
            if wanted and self._camera_sub is None:
                log.info("a ROS subscriber wants %s: camera on", self.pub_camera.topic)
                self._camera_sub = self.robot.subscribe("camera", lambda m: self._put("camera", m))
            elif not wanted and self._camera_sub is not None:
                log.info("no ROS subscriber on %s: camera off", self.pub_camera.topic)
                self._camera_sub.close()
                self._camera_sub = None

    def _timer_loop(self) -> None:
        next_diag = time.monotonic()
        while not self._stop.wait(0.1):
            now = time.monotonic()
            if now >= next_diag:
                next_diag = now + 1.0
                st = self.robot.state
                with contextlib.suppress(Exception):
                    self.pub_diag.publish(
                        convert.diagnostics(st.joints, st.status, self.names_by_id, time.time())
                    )
            self.commands.tick()

    def _report(self, message: str) -> None:
        log.warning("%s", message)
        self._errors.append(message)
        del self._errors[:-50]

    @property
    def errors(self) -> list[str]:
        return list(self._errors)

    def close(self) -> None:
        if self._stop.is_set():
            return
        self._stop.set()
        self.commands.close()
        with self._cond:
            self._cond.notify_all()
        for t in self._threads:
            t.join(timeout=2.0)
        for s in self._subs:
            with contextlib.suppress(Exception):
                s.close()
        with self._camera_lock:
            if self._camera_sub is not None:
                self._camera_sub.close()
                self._camera_sub = None
        self.graph.close()
        self.node.close()
