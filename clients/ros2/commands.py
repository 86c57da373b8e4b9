"""The ROS 2 adapter's command side: cmd_vel, joint_trajectory and the halt / torque / lease
services, each through the arbiter with the adapter's Robot and its lease. One command thread
runs them, so a slow arbiter never blocks Zenoh; the lease is taken when a ROS command needs it
and given back when ROS goes quiet. The :class:`clients.ros2.adapter.Adapter` has one
:class:`RosCommandPort`, made with only what it uses.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from collections.abc import Callable
from typing import Any

from clients.adapter_core import Action, AdapterCore
from clients.rmw import convert, graph
from clients.rmw.types import msg_class
from clients.robot import Robot
from clients.ros2.node import RosNode
from schemas import qos
from schemas.errors import (
    AdapterInputError,
    CommandError,
    DarwinError,
    LeaseBusyError,
    NoLeaseError,
)
from schemas.messages import Event, encode

log = logging.getLogger("darwin.ros2")

CMD_VEL_TIMEOUT = 0.5  # s without a Twist → stop walking (base-controller convention)


class RosCommandPort:
    """ROS's inputs (cmd_vel, joint_trajectory, the services) turned into arbiter commands on
    ``robot``, with the lease policy of :class:`AdapterCore`. :meth:`run` is the command
    thread; :meth:`tick` asks it to look at the clock (deadman, idle release)."""

    def __init__(
        self,
        robot: Robot,
        node: RosNode,
        limits: dict[str, convert.Limit],
        lease_idle: float,
        stop: threading.Event,
        stats: dict[str, int],
        report: Callable[[str], None],
    ) -> None:
        self.robot = robot
        self.node = node
        self.limits = limits
        self.stats = stats  # "rejected" counts the inputs refused
        self._stop = stop
        self._report = report  # the adapter's list of recent errors
        self._cmds: queue.Queue[tuple[str, Any]] = queue.Queue(maxsize=64)
        self.core = AdapterCore(idle_release=lease_idle, deadman=CMD_VEL_TIMEOUT)
        self._make_ros_inputs()

    def tick(self) -> None:
        self._enqueue("tick", None)

    def close(self) -> None:
        """The adapter stops: the lease it holds goes back (the walk stopped first)."""
        if self.core.holding:
            self._release("the adapter stops")

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

    # -- commands --------------------------------------------------------------------------
    def _enqueue(self, kind: str, item: Any) -> None:
        try:
            self._cmds.put_nowait((kind, item))
        except queue.Full:
            if kind != "tick":
                self._report(f"dropped a {kind} command: the command queue is full")

    def run(self) -> None:
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
        if not self.core.before_command(time.monotonic()):
            return True
        try:
            self.robot.acquire()
        except LeaseBusyError as exc:
            self._refused(exc)
            return False
        self.core.acquired(time.monotonic())
        self._say("ros2_lease", "the ROS adapter took the control lease")
        return True

    def _refused(self, exc: Exception) -> None:
        """Someone else holds the lease: say so once per burst of ROS commands."""
        if self.core.refused(time.monotonic()):
            self._say("ros2_refused", f"ROS command ignored: {exc}")

    def _command(self, fn: Any, *args: Any, **kw: Any) -> Any:
        try:
            return fn(*args, **kw)
        except (NoLeaseError, LeaseBusyError):
            self.core.lost()  # lost it (idle timeout…): take it again next time
            raise

    def _on_twist(self, ros_type: str, msg: Any) -> None:
        self.core.active(time.monotonic())
        try:
            walk = convert.walk_from_twist(ros_type, msg)
        except AdapterInputError as exc:
            self._reject(str(exc))
            return
        self.core.walk_seen(time.monotonic())
        if walk.zero:
            if self.core.walking:
                self._stop_walk()
            return
        if not self._take_lease():
            return
        try:
            self._command(self.robot.walk, walk.x, walk.y, walk.turn)
            self.core.walk(time.monotonic())
        except LeaseBusyError as exc:
            self._refused(exc)
        except CommandError as exc:
            self._reject(f"cmd_vel refused by the arbiter: {exc}")

    def _stop_walk(self) -> None:
        self.core.walk_stopped()
        with contextlib.suppress(DarwinError):
            self._command(self.robot.walk_stop)

    def _on_trajectory(self, msg: Any) -> None:
        """The whole trajectory goes to the daemon once and plays in its loop (as a ros2_control
        controller would), never point by point across the network."""
        self.core.active(time.monotonic())
        try:
            joints, points = convert.trajectory_command(msg, self.limits)
        except AdapterInputError as exc:
            self._reject(str(exc))
            return
        took = not self.core.holding
        if not self._take_lease():
            return
        try:
            applied = self._command(self.robot.trajectory, joints, points)
        except CommandError as exc:
            self._reject(f"joint_trajectory refused by the arbiter: {exc}")
            if took and self.core.holding:
                self._release("its only command was refused")  # keep no lease for nothing
            return
        # Playing counts as activity: the lease is not given back while the robot follows it.
        now = time.monotonic()
        self.core.active(now, until=now + float(applied.get("duration", 0.0)))

    def _on_tick(self) -> None:
        actions = self.core.tick(time.monotonic())
        if Action.STOP_WALK in actions:
            log.info("no cmd_vel for %.1f s: stopping the walk", CMD_VEL_TIMEOUT)
            self._stop_walk()
        if Action.RELEASE in actions:
            self._release("ROS went quiet")

    def _release(self, why: str) -> None:
        if self.core.walking:
            self._stop_walk()  # the arbiter stops it too when the lease ends; do not rely on it
        self.core.released()
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
        self.core.walk_stopped()
        try:
            self.robot.halt()
        except DarwinError as exc:
            return self._trigger_response(False, str(exc))
        return self._trigger_response(True, "halted: walking and behaviours stopped, pose held")

    def _srv_torque(self, req: Any) -> Any:
        if not self._take_lease():
            return self._setbool_response(False, "the control lease is held by someone else")
        try:
            self._command(self.robot.torque, bool(req.data))
        except DarwinError as exc:
            return self._setbool_response(False, str(exc))
        return self._setbool_response(True, f"torque {'on' if req.data else 'off'}")

    def _srv_lease(self, req: Any) -> Any:
        self.core.active(time.monotonic())
        if req.data:
            try:
                self.robot.acquire()
            except DarwinError as exc:
                return self._setbool_response(False, str(exc))
            self.core.acquired(time.monotonic(), auto=False)
            return self._setbool_response(True, "the ROS adapter holds the control lease")
        if not self.core.holding:
            return self._setbool_response(True, "the ROS adapter did not hold the lease")
        self._release("lease service called with false")
        return self._setbool_response(True, "lease released; motion brought to a safe stop")

    # -- reporting -------------------------------------------------------------------------
    def _reject(self, message: str) -> None:
        self.stats["rejected"] += 1
        self._report(message)


    def _say(self, kind: str, message: str) -> None:
        """Log and publish an event, so the TUI and recorder see what ROS did."""
        log.warning("%s", message)
        with contextlib.suppress(Exception):
            self.robot.session.put(
                self.robot.keys.events,
                encode(Event(kind=kind, message=message, data={"client": self.robot.name})),
                **qos.for_key(self.robot.keys.events).kwargs(),
            )
