"""The one Zenoh helper every program uses: endpoints, robot name, session config.

Resolution order for where to connect and which robot: explicit arguments (``--connect``,
``--robot``), then ``DARWIN_ENDPOINT`` / ``DARWIN_ROBOT``, then the local defaults.
Multicast scouting is always off: robots on one network must never find each other by accident.

Credentials (who a client is: user/password, TLS certificates) are :mod:`schemas.credentials`,
importable from here too.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import socket
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import zenoh

# Who a client is: every client and the daemon take these from here, so they stay importable.
from schemas.credentials import Credentials as Credentials
from schemas.credentials import add_credential_arguments as add_credential_arguments
from schemas.credentials import credential_args as credential_args
from schemas.credentials import credential_env as credential_env
from schemas.credentials import credentials as credentials
from schemas.credentials import credentials_from_args as credentials_from_args
from schemas.credentials import login_free_env as login_free_env
from schemas.credentials import login_hint as login_hint
from schemas.errors import DarwinError, RobotUnreachableError
from schemas.keys import DEFAULT_ROBOT, check_robot_name

DEFAULT_PORT = 7447
# Zenoh drops (never delivers) any message larger than this that a server receives, so a huge
# payload costs no Python time at all; smaller oversized requests get a clear error from
# ``schemas.query``. Big enough for a rendered 640×480 camera frame (a reply the daemon
# receives); small, because Zenoh buffers a fragmented message up to this size before it drops it.
MAX_MESSAGE_BYTES = 2 * 1024 * 1024
# Video never delays control (docs/camera-and-network.md). The kernel's send buffer of each TCP
# or TLS link a listening session (daemon, router) opens, in bytes (Linux doubles it): left to
# autotuning it grows to megabytes, and on busy Wi-Fi seconds of camera frames waited there ahead
# of a halt's reply, past Zenoh's priorities (the lease was lost). Small, the backlog stays in
# Zenoh's per-priority queues, where video is dropped and control goes first.
SEND_BUFFER_BYTES = 16 * 1024
# A reply waits for the batch being written: ~50 kB frames go out in batches this small.
BATCH_BYTES = 16 * 1024
# Video (DATA_LOW) batches a link queues: a whole frame's fragments fit, or it is dropped.
VIDEO_QUEUE_BATCHES = 8
# Telemetry (DATA) batches a link queues: each express message takes a batch, and a tick puts
# up to five at once (joints, IMU, the policy's observation and answer, a ball detection); with
# Zenoh's 2 the last ones of a tick were dropped whenever the link's sender was a moment late.
TELEMETRY_QUEUE_BATCHES = 8
# How long (µs) a message that may not be dropped (a declaration, a reply; a replay's samples)
# waits for room in a congested client's link queue before Zenoh closes that client's transport.
# The daemon's: short, because meanwhile its whole session stalls (server_config says more).
DAEMON_BLOCK_WAIT_US = 500_000
DEFAULT_ENDPOINT = f"tcp/127.0.0.1:{DEFAULT_PORT}"
ENV_ENDPOINT = "DARWIN_ENDPOINT"
ENV_ROBOT = "DARWIN_ROBOT"


@dataclass(frozen=True)
class Target:
    """The robot a client connects to: its endpoint, its name and the login to present."""

    endpoint: str
    robot: str
    credentials: Credentials | None = None


def resolve(
    endpoint: str | None = None, robot: str | None = None, creds: Credentials | None = None
) -> Target:
    """Where to connect, which robot and as whom (``creds`` None: from the environment)."""
    ep = endpoint or os.environ.get(ENV_ENDPOINT) or DEFAULT_ENDPOINT
    name = robot or os.environ.get(ENV_ROBOT) or DEFAULT_ROBOT
    check_endpoint(ep)
    return Target(ep, check_robot_name(name), creds if creds is not None else credentials())


def resolve_args(args: argparse.Namespace, robot: str | None = None) -> Target:
    """:func:`resolve` for a program with :func:`add_target_arguments`."""
    return resolve(
        getattr(args, "connect", None),
        robot or getattr(args, "robot", None),
        credentials_from_args(args),
    )


def add_target_arguments(
    parser: argparse.ArgumentParser, robot_default: str = "", several: bool = False
) -> None:
    """``--connect``, ``--robot`` and the credentials, the same for every client of the key
    space (``several``: ``--robot`` may repeat, a list of names, for clients of several robots
    like the recorder)."""
    parser.add_argument(
        "--connect",
        metavar="ENDPOINT",
        help=f"Zenoh endpoint of the robot, e.g. tcp/10.0.0.5:7447 (default: ${ENV_ENDPOINT}, "
        f"else {DEFAULT_ENDPOINT})",
    )
    parser.add_argument(
        "--robot",
        metavar="NAME",
        action="append" if several else "store",
        help=f"robot name (default: {robot_default}${ENV_ROBOT}, else {DEFAULT_ROBOT})"
        + ("; repeat it for several robots, '*' for every robot" if several else ""),
    )
    add_credential_arguments(parser)


def check_endpoint(endpoint: str) -> str:
    proto, sep, rest = endpoint.partition("/")
    if not sep or proto not in {"tcp", "udp", "tls", "quic", "ws", "unixsock-stream"} or not rest:
        raise ValueError(
            f"endpoint {endpoint!r} is not a Zenoh locator; write it like tcp/127.0.0.1:7447"
        )
    return endpoint


def _config(
    mode: str,
    listen: list[str],
    connect: list[str],
    lease_ms: int | None,
    max_message_bytes: int | None = None,
) -> zenoh.Config:
    conf = zenoh.Config()
    if max_message_bytes is not None:
        conf.insert_json5("transport/link/rx/max_message_size", str(int(max_message_bytes)))
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("listen/endpoints", json.dumps(listen))
    conf.insert_json5("connect/endpoints", json.dumps(connect))
    if mode == "client":
        # A client whose link drops reconnects to its endpoint by itself, forever (Zenoh's
        # default for a closed session); retry at least every second rather than every 4 s,
        # so a notebook sees the robot again soon after a cut link comes back.
        conf.insert_json5(
            "connect/retry",
            json.dumps({"period_init_ms": 250, "period_max_ms": 1000, "period_increase_factor": 2}),
        )
    if lease_ms is not None:
        # A dead client's liveliness token goes after the link lease: keep it short so the
        # arbiter brings the robot to a safe stop quickly when a controller vanishes.
        conf.insert_json5("transport/link/tx/lease", str(lease_ms))
        conf.insert_json5("transport/link/tx/keep_alive", "4")
    return conf


SERVER_MODES = ("peer", "router")


def server_config(
    listen: list[str],
    lease_ms: int | None = 3000,
    max_message_bytes: int = MAX_MESSAGE_BYTES,
    mode: str = "peer",
    block_wait_us: int = DAEMON_BLOCK_WAIT_US,
) -> zenoh.Config:
    """A session that listens (daemon, simulator world, replay): a peer, or a Zenoh router
    (``mode="router"``) that other machines' sessions, ROS 2 nodes included, join as clients.
    A peer closes the link of a client that takes no message for ``block_wait_us`` while a
    message that may not be dropped waits for it."""
    if mode not in SERVER_MODES:
        raise ValueError(f"zenoh mode {mode!r} is not one of {', '.join(SERVER_MODES)}")
    for ep in listen:
        check_endpoint(ep)
    conf = _config(mode, listen, [], lease_ms, max_message_bytes)
    for proto in ("tcp", "tls"):
        conf.insert_json5(f"transport/link/{proto}/so_sndbuf", str(SEND_BUFFER_BYTES))
    conf.insert_json5("transport/link/tx/batch_size", str(BATCH_BYTES))
    conf.insert_json5("transport/link/tx/queue/size/data_low", str(VIDEO_QUEUE_BATCHES))
    conf.insert_json5("transport/link/tx/queue/size/data", str(TELEMETRY_QUEUE_BATCHES))
    congestion = "transport/link/tx/queue/congestion_control"
    if mode == "peer":
        # The daemon's session (a router keeps Zenoh's defaults: with these it closed a lossy
        # operator's link over and over, and dropped more for slow observers).
        # It publishes every tick from its motion thread; a publication (DROP) to a client whose
        # link is congested waits this long (µs) for room in that link's queue, in that thread:
        # Zenoh's 1000 let one slow client hold up every other subscriber, and the tick.
        conf.insert_json5(f"{congestion}/drop/wait_before_drop", "50")
        # A message that may not be dropped (a declaration, a reply) to a client whose link is
        # dead with a full queue blocks ``block_wait_us`` before that client's transport closes,
        # and meanwhile the whole session stalls: with Zenoh's 5 s every other client of the
        # robot went silent (leases and heartbeats too) after one operator's link was cut. A
        # replay passes its own (clients/recording/replay.py): its samples may not be lost.
        conf.insert_json5(f"{congestion}/block/wait_before_close", str(int(block_wait_us)))
    return conf


def client_config(
    endpoint: str, lease_ms: int | None = 3000, creds: Credentials | None = None
) -> zenoh.Config:
    """A client session that connects to one explicit endpoint, as ``creds`` (None: the
    credentials of the environment and the client file)."""
    conf = _config("client", [], [check_endpoint(endpoint)], lease_ms)
    (creds if creds is not None else credentials()).apply(conf)
    return conf


def open_server(listen: list[str], lease_ms: int | None = 3000) -> zenoh.Session:
    return zenoh.open(server_config(listen, lease_ms))


def open_client(
    endpoint: str | Target, lease_ms: int | None = 3000, creds: Credentials | None = None
) -> zenoh.Session:
    if isinstance(endpoint, Target):
        creds = creds or endpoint.credentials
        endpoint = endpoint.endpoint
    return zenoh.open(client_config(endpoint, lease_ms, creds))


# The fix a client prints when the robot's endpoint does not answer.
CONNECT_HINT = "is the daemon running there (`darwin up`)? Check --connect / DARWIN_ENDPOINT"


def zenoh_reason(exc: BaseException) -> str:
    """Zenoh's error in one line, without its Rust source paths."""
    text = str(exc).strip()
    if "already in use" in text.lower():
        return "the address is already in use"
    text = text.splitlines()[0] if text else type(exc).__name__
    return text.split(" at /", 1)[0][:160].rstrip()


def open_session(
    conf: zenoh.Config,
    failed: str,
    hint: str | Callable[[str], str],
    error: type[DarwinError] = RobotUnreachableError,
) -> zenoh.Session:
    """Open a Zenoh session, or raise ``error`` (:class:`RobotUnreachableError` unless told)
    with one line for the user: ``"{failed}: {reason}; {hint}"``, i.e. what could not be
    opened, Zenoh's reason (:func:`zenoh_reason`) and the fix, e.g. "pass e.g. --connect
    tcp/127.0.0.1:7447". ``hint`` may be a function of the reason when the fix depends on it.
    Every program opens its sessions through here (or :func:`connect`)."""
    try:
        return zenoh.open(conf)
    except zenoh.ZError as exc:
        reason = zenoh_reason(exc)
        fix = hint(reason) if callable(hint) else hint
        raise error(f"{failed}: {reason}; {fix}") from exc


def connect(
    endpoint: str | Target,
    failed: str | None = None,
    hint: str = CONNECT_HINT,
    creds: Credentials | None = None,
    lease_ms: int | None = 3000,
) -> zenoh.Session:
    """:func:`open_client` whose failure is a :class:`RobotUnreachableError` saying so in one
    line (``failed``, default "cannot open a Zenoh session to ENDPOINT"; the reason; ``hint``)."""
    if isinstance(endpoint, Target):
        creds = creds or endpoint.credentials
        endpoint = endpoint.endpoint
    conf = client_config(endpoint, lease_ms, creds)
    return open_session(conf, failed or f"cannot open a Zenoh session to {endpoint}", hint)


def free_tcp_port(host: str = "127.0.0.1") -> int:
    """A TCP port nobody listens on right now (tests, ``darwin up`` with port 0).

    Chosen below the kernel's range for outgoing connections (``ip_local_port_range``): a port
    from that range can be taken by any client's connection between this choice and the
    listener's bind (seen: "address already in use" in CI), one below it only by a listener."""
    low = _ephemeral_low()
    for _ in range(64):
        port = random.randrange(10000, low) if low > 11000 else 0
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind((host, port))
            except OSError:
                continue
            return int(s.getsockname()[1])
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def _ephemeral_low() -> int:
    try:
        return int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 0


def endpoint_host_port(endpoint: str) -> tuple[str, int]:
    rest = endpoint.split("/", 1)[1]
    host, _, port = rest.rpartition(":")
    return host.strip("[]"), int(port)
