"""``darwin ros2``: the robot as a native ROS 2 node over rmw_zenoh's wire format.

A client of the key space like the TUI: state comes from the daemon's publications through a
:class:`clients.robot.Robot`, every command goes through the arbiter with that Robot's lease.
Zenoh callbacks only hand work over: one publishing thread converts and puts, one command thread
talks to the arbiter, so neither a slow arbiter nor a burst of ROS traffic blocks Zenoh.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from dataclasses import dataclass
from typing import Any

import zenoh

from clients.robot import Robot
from clients.ros2 import convert, graph
from clients.ros2.node import GraphWatch, RosNode
from clients.ros2.types import msg_class
from schemas import qos
from schemas.body import Body
from schemas.errors import CommandError, DarwinError, LeaseBusyError, NoLeaseError
from schemas.messages import CameraFrame, Event, Imu, Joints, World, encode
from schemas.urdf import body_from_config_reply, to_urdf

log = logging.getLogger("darwin.ros2")

CMD_VEL_TIMEOUT = 0.5  # s without a Twist → stop walking (base-controller convention)
CAMERA_TOPIC = "camera/image_raw/compressed"


@dataclass
class Options:
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
        self.names_by_id = {j.servo_id: j.name for j in self.body.servo_joints()}
        self.limits = {
            j.name: convert.Limit(j.servo_id, j.lower, j.upper) for j in self.body.servo_joints()
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
        # Commands
        self._cmds: queue.Queue[tuple[str, Any]] = queue.Queue(maxsize=64)
        self._lease_auto = False
        self._holding = False
        self._last_cmd = 0.0
        self._walking = False
        self._last_twist = 0.0
        self._refused_burst = False
        self._threads = [
            threading.Thread(target=self._publish_loop, name="ros2-publish", daemon=True),
            threading.Thread(target=self._command_loop, name="ros2-commands", daemon=True),
            threading.Thread(target=self._timer_loop, name="ros2-timers", daemon=True),
        ]
        self._subs = [
            robot.subscribe("joints", lambda m: self._put("joints", m)),
            robot.subscribe("imu", lambda m: self._put("imu", m)),
            robot.subscribe("world", lambda m: self._put("world", m)),
        ]
        self._make_ros_inputs()
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

    def _make_ros_inputs(self) -> None:
        n = self.node
        n.subscription(
            "cmd_vel",
            ["geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped"],
            graph.DEFAULT_QOS,
            lambda t, m, _a: self._enqueue("twist", (t, m)),
            self._report,
        )
        n.subscription(
            "joint_trajectory",
            ["trajectory_msgs/msg/JointTrajectory"],
            graph.DEFAULT_QOS,
            lambda _t, m, _a: self._enqueue("trajectory", m),
            self._report,
        )
        n.service("halt", "std_srvs/srv/Trigger", self._srv_halt, self._report)
        n.service("torque", "std_srvs/srv/SetBool", self._srv_torque, self._report)
        n.service("lease", "std_srvs/srv/SetBool", self._srv_lease, self._report)

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
            self._enqueue("tick", None)

    # -- commands --------------------------------------------------------------------------
    def _enqueue(self, kind: str, item: Any) -> None:
        try:
            self._cmds.put_nowait((kind, item))
        except queue.Full:
            if kind != "tick":
                self._report(f"dropped a {kind} command: the command queue is full")

    def _command_loop(self) -> None:
        while not self._stop.is_set():
            try:
                kind, item = self._cmds.get(timeout=0.5)
            except queue.Empty:
                continue
            try:
                if kind == "twist":
                    self._on_twist(*item)
                elif kind == "trajectory":
                    self._on_trajectory(item)
                elif kind == "tick":
                    self._on_tick()
            except Exception as exc:
                log.exception("command %s failed", kind)
                self._report(f"{kind} failed: {exc}")

    def _take_lease(self) -> bool:
        """The lease for ROS commands: taken when free, as the gateway does for its clients."""
        if self._holding:
            return True
        try:
            self.robot.acquire()
        except LeaseBusyError as exc:
            self._refused(exc)
            return False
        self._holding = True
        self._lease_auto = True
        self._say("ros2_lease", "the ROS adapter took the control lease")
        return True

    def _refused(self, exc: Exception) -> None:
        """Someone else holds the lease: say so once per burst of ROS commands."""
        if not self._refused_burst:
            self._refused_burst = True
            self._say("ros2_refused", f"ROS command ignored: {exc}")

    def _command(self, fn: Any, *args: Any, **kw: Any) -> Any:
        try:
            return fn(*args, **kw)
        except (NoLeaseError, LeaseBusyError):
            self._holding = False  # lost it (idle timeout…): take it again next time
            raise

    def _on_twist(self, ros_type: str, msg: Any) -> None:
        self._last_cmd = time.monotonic()
        try:
            walk = convert.walk_from_twist(ros_type, msg)
        except convert.CommandRejected as exc:
            self._reject(str(exc))
            return
        self._last_twist = time.monotonic()
        if walk.zero:
            if self._walking:
                self._stop_walk()
            return
        if not self._take_lease():
            return
        try:
            self._command(self.robot.walk, walk.x, walk.y, walk.turn)
            self._walking = True
        except LeaseBusyError as exc:
            self._refused(exc)
        except CommandError as exc:
            self._reject(f"cmd_vel refused by the arbiter: {exc}")

    def _stop_walk(self) -> None:
        self._walking = False
        with contextlib.suppress(DarwinError):
            self._command(self.robot.walk_stop)

    def _on_trajectory(self, msg: Any) -> None:
        """The whole trajectory goes to the daemon once and plays in its loop (as a ros2_control
        controller would), never point by point across the network."""
        self._last_cmd = time.monotonic()
        try:
            joints, points = convert.trajectory_command(msg, self.limits)
        except convert.CommandRejected as exc:
            self._reject(str(exc))
            return
        took = not self._holding
        if not self._take_lease():
            return
        try:
            applied = self._command(self.robot.trajectory, joints, points)
        except CommandError as exc:
            self._reject(f"joint_trajectory refused by the arbiter: {exc}")
            if took and self._holding:
                self._release("its only command was refused")  # keep no lease for nothing
            return
        # Playing counts as activity: the lease is not given back while the robot follows it.
        self._last_cmd = time.monotonic() + float(applied.get("duration", 0.0))

    def _on_tick(self) -> None:
        now = time.monotonic()
        if self._walking and now - self._last_twist > CMD_VEL_TIMEOUT:
            log.info("no cmd_vel for %.1f s: stopping the walk", CMD_VEL_TIMEOUT)
            self._stop_walk()
        if now - self._last_cmd > CMD_VEL_TIMEOUT:
            self._refused_burst = False  # the next refused command is a new burst
        if self._holding and self._lease_auto and now - self._last_cmd > self.options.lease_idle:
            self._release("ROS went quiet")

    def _release(self, why: str) -> None:
        if self._walking:
            self._stop_walk()  # the arbiter stops it too when the lease ends; do not rely on it
        self._walking = False
        self._holding = False
        self._lease_auto = False
        # The arbiter brings whatever the lease started to a safe stop when it ends.
        with contextlib.suppress(DarwinError):
            self.robot.release()
        self._say("ros2_lease", f"the ROS adapter released the control lease ({why})")

    # -- services (worker threads) ---------------------------------------------------------
    def _trigger_response(self, ok: bool, message: str) -> Any:
        return msg_class("std_srvs/srv/Trigger_Response")(success=ok, message=message)

    def _setbool_response(self, ok: bool, message: str) -> Any:
        return msg_class("std_srvs/srv/SetBool_Response")(success=ok, message=message)

    def _srv_halt(self, _req: Any) -> Any:
        self._walking = False
        try:
            self.robot.halt()
        except DarwinError as exc:
            return self._trigger_response(False, str(exc))
        return self._trigger_response(True, "halted: walking and behaviours stopped, pose held")

    def _srv_torque(self, req: Any) -> Any:
        self._last_cmd = time.monotonic()
        if not self._take_lease():
            return self._setbool_response(False, "the control lease is held by someone else")
        try:
            self._command(self.robot.torque, bool(req.data))
        except DarwinError as exc:
            return self._setbool_response(False, str(exc))
        return self._setbool_response(True, f"torque {'on' if req.data else 'off'}")

    def _srv_lease(self, req: Any) -> Any:
        self._last_cmd = time.monotonic()
        if req.data:
            try:
                self.robot.acquire()
            except DarwinError as exc:
                return self._setbool_response(False, str(exc))
            self._holding, self._lease_auto = True, False
            return self._setbool_response(True, "the ROS adapter holds the control lease")
        if not self._holding:
            return self._setbool_response(True, "the ROS adapter did not hold the lease")
        self._release("lease service called with false")
        return self._setbool_response(True, "lease released; motion brought to a safe stop")

    # -- reporting -------------------------------------------------------------------------
    def _reject(self, message: str) -> None:
        self.stats["rejected"] += 1
        self._report(message)

    def _report(self, message: str) -> None:
        log.warning("%s", message)
        self._errors.append(message)
        del self._errors[:-50]

    def _say(self, kind: str, message: str) -> None:
        """Log and publish an event, so the TUI and recorder see what ROS did."""
        log.warning("%s", message)
        with contextlib.suppress(Exception):
            self.robot.session.put(
                self.robot.keys.events,
                encode(Event(kind=kind, message=message, data={"client": self.robot.name})),
                **qos.for_key(self.robot.keys.events).kwargs(),
            )

    @property
    def errors(self) -> list[str]:
        return list(self._errors)

    def close(self) -> None:
        if self._stop.is_set():
            return
        self._stop.set()
        if self._holding:
            self._release("the adapter stops")
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
