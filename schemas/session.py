"""The one Zenoh helper every program uses: endpoints, robot name, session config.

Resolution order for where to connect and which robot: explicit arguments (``--connect``,
``--robot``), then ``DARWIN_ENDPOINT`` / ``DARWIN_ROBOT``, then the local defaults.
Multicast scouting is always off: robots on one network must never find each other by accident.

Credentials, the same for every client (:class:`Credentials`), first found wins per item:
``--user`` / ``--password-file`` / ``--cert`` / ``--key`` / ``--ca`` (or ``Robot(user=…,
password=…)``), then ``DARWIN_USER`` / ``DARWIN_PASSWORD`` / ``DARWIN_PASSWORD_FILE`` /
``DARWIN_CERT`` / ``DARWIN_KEY`` / ``DARWIN_CA``, then the user's client file
(``$DARWIN_CLIENT_CONFIG``, else ``$XDG_CONFIG_HOME/darwin/client.toml``, else
``~/.config/darwin/client.toml``) with keys ``user``, ``password_file`` (or ``password``),
``cert``, ``key``, ``ca``. A user/password logs in (Zenoh ``transport/auth/usrpwd``); a
certificate and key make a TLS client certificate (mutual TLS, the common name is the user);
a CA alone lets a ``tls/`` endpoint check the robot's certificate.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import socket
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from schemas.extras import require
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
DEFAULT_ENDPOINT = f"tcp/127.0.0.1:{DEFAULT_PORT}"
ENV_ENDPOINT = "DARWIN_ENDPOINT"
ENV_ROBOT = "DARWIN_ROBOT"
ENV_USER = "DARWIN_USER"
ENV_PASSWORD = "DARWIN_PASSWORD"
ENV_PASSWORD_FILE = "DARWIN_PASSWORD_FILE"
ENV_CERT = "DARWIN_CERT"
ENV_KEY = "DARWIN_KEY"
ENV_CA = "DARWIN_CA"
ENV_CLIENT_CONFIG = "DARWIN_CLIENT_CONFIG"
LOGIN_ENV = (ENV_USER, ENV_PASSWORD, ENV_PASSWORD_FILE, ENV_CERT, ENV_KEY, ENV_CA)


def login_free_env(environ: Mapping[str, str]) -> dict[str, str]:
    """``environ`` for a child program whose login is all in its arguments: no login
    variables, and no client file (``/dev/null`` is not a file, so none is read)."""
    env = {k: v for k, v in environ.items() if k not in LOGIN_ENV}
    env[ENV_CLIENT_CONFIG] = os.devnull
    return env


@dataclass(frozen=True)
class Credentials:
    """Who a client is: a user/password login and/or a TLS client certificate."""

    user: str | None = None
    password: str | None = field(default=None, repr=False)
    cert: str | None = None
    key: str | None = None
    ca: str | None = None

    def __post_init__(self) -> None:
        if self.password is not None and not self.user:
            raise ValueError("a password needs a user name: pass --user (or DARWIN_USER)")
        if bool(self.cert) != bool(self.key):
            raise ValueError("a client certificate needs both --cert and --key")

    @property
    def identity(self) -> str | None:
        """The name access control knows this client by (user, else the certificate's CN)."""
        if self.user:
            return self.user
        if self.cert:
            x509 = require("cryptography.x509", "reading a client certificate's name")
            cert = x509.load_pem_x509_certificate(Path(self.cert).read_bytes())
            cn = x509.oid.NameOID.COMMON_NAME
            return str(cert.subject.get_attributes_for_oid(cn)[0].value)
        return None

    def apply(self, conf: zenoh.Config) -> None:
        if self.user and self.password is not None:
            conf.insert_json5("transport/auth/usrpwd/user", json.dumps(self.user))
            conf.insert_json5("transport/auth/usrpwd/password", json.dumps(self.password))
        if self.ca:
            conf.insert_json5("transport/link/tls/root_ca_certificate", json.dumps(self.ca))
        if self.cert and self.key:
            # Zenoh sends the client certificate only with mTLS on at the connecting side too.
            conf.insert_json5("transport/link/tls/enable_mtls", "true")
            conf.insert_json5("transport/link/tls/connect_certificate", json.dumps(self.cert))
            conf.insert_json5("transport/link/tls/connect_private_key", json.dumps(self.key))


def login_hint(
    creds: Credentials | None, options: str = "--user/--password-file or --cert/--key"
) -> str:
    """What to check when a session to ``creds``' endpoint does not open: the login it used
    (an endpoint with logins refuses a wrong one, or none, when the link opens)."""
    try:
        who = creds.identity if creds is not None else None
    except (OSError, ValueError, ImportError):  # a hint never fails (no 'security' extra)
        who = None
    if who:
        return (f" as {who}: check the user, password or certificate (a robot with --auth or "
                "--secure refuses a wrong one at connection)")
    return (f"; if it requires a login (--auth or --secure), pass {options} "
            "(docs/security.md)")


def client_config_path() -> Path:
    explicit = os.environ.get(ENV_CLIENT_CONFIG)
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "darwin" / "client.toml"


def _read_secret(path: str, what: str) -> str:
    try:
        text = Path(path).expanduser().read_text()
    except OSError as exc:
        raise ValueError(f"cannot read the {what} {path}: {exc.strerror or exc}") from None
    secret = text.strip("\r\n")
    if not secret or "\n" in secret:
        raise ValueError(f"the {what} {path} must hold the password alone, on one line")
    return secret


def credentials(
    user: str | None = None,
    password: str | None = None,
    password_file: str | None = None,
    cert: str | None = None,
    key: str | None = None,
    ca: str | None = None,
    fallback: bool = True,
) -> Credentials:
    """Credentials from explicit values, else (``fallback``) the environment, else the client
    file."""
    env = os.environ if fallback else {}
    file_conf: dict[str, Any] = {}
    path = client_config_path()
    if fallback and path.is_file():
        try:
            file_conf = tomllib.loads(path.read_text())
        except (OSError, tomllib.TOMLDecodeError) as exc:
            raise ValueError(f"cannot read the client file {path}: {exc}") from None

    def pick(explicit: str | None, env_name: str, file_key: str) -> str | None:
        value = explicit or env.get(env_name) or file_conf.get(file_key)
        return str(value) if value else None

    user = pick(user, ENV_USER, "user")
    if password is None:
        password_file = pick(password_file, ENV_PASSWORD_FILE, "password_file")
        if password_file:
            password = _read_secret(password_file, "password file")
        else:
            password = env.get(ENV_PASSWORD) or file_conf.get("password")
    if user and password is None:
        raise ValueError(
            f"user {user!r} has no password: pass --password-file FILE (or {ENV_PASSWORD}, or "
            f"password_file in {path})"
        )
    return Credentials(
        user, password, pick(cert, ENV_CERT, "cert"), pick(key, ENV_KEY, "key"),
        pick(ca, ENV_CA, "ca"),
    )


def credentials_from_args(args: argparse.Namespace) -> Credentials:
    """The credentials of a program with :func:`add_target_arguments`."""
    return credentials(
        user=getattr(args, "user", None),
        password_file=getattr(args, "password_file", None),
        cert=getattr(args, "cert", None),
        key=getattr(args, "key", None),
        ca=getattr(args, "ca", None),
    )


@dataclass(frozen=True)
class Target:
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
        getattr(args, "connect", None), robot or getattr(args, "robot", None),
        credentials_from_args(args),
    )


def credential_args(args: argparse.Namespace) -> list[str]:
    """The credential options given to this program, for a child program (files absolute)."""
    out: list[str] = []
    for opt in ("user", "password_file", "cert", "key", "ca"):
        value = getattr(args, opt, None)
        if value:
            if opt != "user":
                value = str(Path(value).expanduser().resolve())
            out += [f"--{opt.replace('_', '-')}", value]
    return out


def credential_env(creds: Credentials, secrets_dir: Path | None = None) -> dict[str, str]:
    """Environment variables that make a child program log in as ``creds`` (the password as
    a 0600 file in ``secrets_dir`` when given, never in the environment itself)."""
    env: dict[str, str] = {}
    if creds.user:
        env[ENV_USER] = creds.user
    if creds.password is not None and secrets_dir is not None:
        fd = os.open(secrets_dir / "password", os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(creds.password)
        env[ENV_PASSWORD_FILE] = str(secrets_dir / "password")
    for name, value in ((ENV_CERT, creds.cert), (ENV_KEY, creds.key), (ENV_CA, creds.ca)):
        if value:
            env[name] = str(Path(value).resolve())
    return env


def add_credential_arguments(parser: argparse.ArgumentParser) -> None:
    """``--user``/``--password-file``/``--cert``/``--key``/``--ca``, for every client."""
    group = parser.add_argument_group("credentials (see docs/security.md)")
    group.add_argument("--user", help=f"user name to log in as (default: ${ENV_USER})")
    group.add_argument(
        "--password-file",
        metavar="FILE",
        help=f"file holding the password (default: ${ENV_PASSWORD_FILE} or ${ENV_PASSWORD})",
    )
    group.add_argument("--cert", help=f"TLS client certificate, CN = user (default: ${ENV_CERT})")
    group.add_argument("--key", help=f"its private key (default: ${ENV_KEY})")
    group.add_argument("--ca", help=f"CA certificate that signed the robot's (default: ${ENV_CA})")


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
) -> zenoh.Config:
    """A session that listens (daemon, simulator world, replay): a peer, or a Zenoh router
    (``mode="router"``) that other machines' sessions, ROS 2 nodes included, join as clients."""
    if mode not in SERVER_MODES:
        raise ValueError(f"zenoh mode {mode!r} is not one of {', '.join(SERVER_MODES)}")
    for ep in listen:
        check_endpoint(ep)
    conf = _config(mode, listen, [], lease_ms, max_message_bytes)
    for proto in ("tcp", "tls"):
        conf.insert_json5(f"transport/link/{proto}/so_sndbuf", str(SEND_BUFFER_BYTES))
    conf.insert_json5("transport/link/tx/batch_size", str(BATCH_BYTES))
    conf.insert_json5("transport/link/tx/queue/size/data_low", str(VIDEO_QUEUE_BATCHES))
    congestion = "transport/link/tx/queue/congestion_control"
    if mode == "peer":
        # The daemon's session (a router keeps Zenoh's defaults: with these it closed a lossy
        # operator's link over and over, and dropped more for slow observers).
        # It publishes every tick from one thread; a publication (DROP) to a client whose link
        # is congested waits this long (µs) for room in that link's queue, in that thread:
        # Zenoh's 1000 let one slow client hold up every other subscriber.
        conf.insert_json5(f"{congestion}/drop/wait_before_drop", "50")
        # A message that may not be dropped (a declaration, a reply) to a client whose link is
        # dead with a full queue blocks this long (µs) before that client's transport closes,
        # and meanwhile the whole session stalls: with Zenoh's 5 s every other client of the
        # robot went silent (leases and heartbeats too) after one operator's link was cut.
        conf.insert_json5(f"{congestion}/block/wait_before_close", "500000")
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
        endpoint, creds = endpoint.endpoint, creds or endpoint.credentials
    return zenoh.open(client_config(endpoint, lease_ms, creds))


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
            return s.getsockname()[1]
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def _ephemeral_low() -> int:
    try:
        return int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 0


def endpoint_host_port(endpoint: str) -> tuple[str, int]:
    rest = endpoint.split("/", 1)[1]
    host, _, port = rest.rpartition(":")
    return host.strip("[]"), int(port)
