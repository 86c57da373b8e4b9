"""``darwin ros2``: make the robot a ROS 2 node (rmw_zenoh wire format, no ROS needed here)."""

from __future__ import annotations

import argparse
import logging
import os
import sys
import threading

from schemas.keys import ROS_DOMAINS
from schemas.session import (
    Credentials,
    add_target_arguments,
    credentials,
    credentials_from_args,
)
from schemas.signals import on_stop_signals

log = logging.getLogger("darwin.ros2")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_target_arguments(parser)
    parser.add_argument("--domain", type=int, help="ROS domain id (default ROS_DOMAIN_ID, else 0)")
    parser.add_argument("--namespace", help="ROS namespace of every topic (default /<robot>)")
    parser.add_argument("--node-name", default="darwin", help="ROS node name (default darwin)")
    parser.add_argument(
        "--joint-rate", type=float, help="joint_states and tf rate in Hz (default: every tick)"
    )
    parser.add_argument(
        "--router",
        metavar="ENDPOINT",
        help="join an existing rmw_zenohd/zenohd (e.g. tcp/HOST:7447) for the ROS side; "
        "default: ROS nodes reach the robot's own Zenoh endpoint",
    )
    ros = parser.add_argument_group(
        "the ROS side's login (with --router, when that router requires one; default: the "
        "ROS side on the robot's endpoint logs in as --user…)"
    )
    for opt, what in (("user", "user name"), ("password-file", "file holding the password"),
                      ("cert", "TLS client certificate"), ("key", "its private key"),
                      ("ca", "CA certificate of the ROS router's")):
        ros.add_argument(f"--ros-{opt}", metavar="FILE" if "-" in opt else opt.upper(), help=what)
    parser.add_argument(
        "--lease-idle",
        type=float,
        default=10.0,
        help="seconds without ROS commands before a lease the adapter took is released",
    )


def _domain(value: int | None) -> int:
    if value is not None:
        domain = value
    else:
        raw = os.environ.get("ROS_DOMAIN_ID", "0") or "0"
        try:
            domain = int(raw)
        except ValueError:
            raise SystemExit(
                f"darwin ros2: ROS_DOMAIN_ID={raw!r} is not a number; unset it or fix it"
            ) from None
    if domain not in ROS_DOMAINS:
        raise SystemExit(
            f"darwin ros2: domain {domain} is outside ROS's {ROS_DOMAINS[0]}..{ROS_DOMAINS[-1]}; "
            "pass --domain"
        )
    return domain


def ros_credentials(
    args: argparse.Namespace, robot_side: Credentials, robot_endpoint: str
) -> Credentials:
    """Who the ROS-side session logs in as: ``--ros-user``… when given (a ROS router has
    identities of its own), else on the robot's own endpoint as the robot side does, else
    nobody (a router that requires a login then refuses with a line saying so)."""
    given = {k: getattr(args, f"ros_{k}", None)
             for k in ("user", "password_file", "cert", "key", "ca")}
    if any(given.values()):
        return credentials(**given, fallback=False)
    return Credentials() if args.router and args.router != robot_endpoint else robot_side


def run(args: argparse.Namespace) -> int:
    from clients.rmw.graph import check_namespace
    from clients.robot import Robot
    from clients.ros2.adapter import Adapter, Options
    from schemas.errors import DarwinError, RobotUnreachableError
    from schemas.session import check_endpoint, client_config, login_hint, open_session

    domain = _domain(args.domain)
    creds = credentials_from_args(args)
    robot = Robot(args.connect, args.robot, name="ros2", credentials=creds)
    ros_session = None
    adapter = None
    try:
        robot.check_protocol(3.0)
        if not robot.alive(timeout=3.0):
            print(
                f"darwin ros2: no daemon for robot {robot.target.robot!r} at "
                f"{robot.target.endpoint}; start it with `darwin up` or fix --connect/--robot",
                file=sys.stderr,
            )
            return 1
        namespace = args.namespace or f"/{robot.target.robot}"
        try:
            check_namespace(namespace)
        except ValueError as exc:
            print(f"darwin ros2: {exc}", file=sys.stderr)
            return 2
        if args.joint_rate is not None and not args.joint_rate > 0:
            print(
                f"darwin ros2: --joint-rate {args.joint_rate} must be above 0 Hz", file=sys.stderr
            )
            return 2
        # The ROS side gets a session of its own, configured like rmw_zenoh's (timestamping on:
        # transient-local history needs it), on the robot's endpoint or on the ROS router; it
        # logs in as the adapter does (a router with logins refuses a session without one).
        ros_endpoint = args.router or robot.target.endpoint
        try:
            ros_creds = ros_credentials(args, creds, robot.target.endpoint)
        except ValueError as exc:
            print(f"darwin ros2: the ROS side's login: {exc}", file=sys.stderr)
            return 2
        failed = f"cannot open the ROS session at {ros_endpoint}"
        hint = login_hint(ros_creds, "--ros-user/--ros-password-file or --ros-cert/--ros-key")
        fix = f"is rmw_zenohd (or zenohd, or `darwin up`) running there{hint}"
        try:
            conf = client_config(check_endpoint(ros_endpoint), creds=ros_creds)
            conf.insert_json5("timestamping/enabled", "true")
            ros_session = open_session(conf, failed, fix)
        except ValueError as exc:
            print(f"darwin ros2: {failed}: {exc}; {fix}", file=sys.stderr)
            return 1
        except RobotUnreachableError as exc:
            print(f"darwin ros2: {exc}", file=sys.stderr)
            return 1
        options = Options(domain, namespace, args.node_name, args.joint_rate, args.lease_idle)
        adapter = Adapter(robot, ros_session, options)
        print(f"ros2: domain {domain} namespace {namespace} node {args.node_name}", flush=True)
        print(f"ros2 zenoh: {ros_endpoint}", flush=True)
        stop = threading.Event()
        on_stop_signals(lambda _signum: stop.set())
        stop.wait()
        return 0
    except DarwinError as exc:
        print(f"darwin ros2: {exc}", file=sys.stderr)
        return 1
    finally:
        if adapter is not None:
            adapter.close()
        if ros_session is not None:
            ros_session.close()
        robot.close()
