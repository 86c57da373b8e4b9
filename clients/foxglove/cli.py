"""``darwin foxglove``: a Foxglove WebSocket server for the robot's key space.

Prints ``foxglove: ws://HOST:PORT`` once it serves (port 0 becomes the real port), then runs
until Ctrl-C or SIGTERM. Open Foxglove, "Open connection", Foxglove WebSocket, that address.
"""

from __future__ import annotations

import argparse
import signal
import threading

from clients.listen import add_server_arguments, parse_listen
from schemas.errors import ConfigError
from schemas.session import credentials_from_args

DEFAULT_LISTEN = "127.0.0.1:8765"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_server_arguments(parser, DEFAULT_LISTEN, "Foxglove connects")
    parser.add_argument(
        "--tf-rate",
        type=float,
        default=0.0,
        metavar="HZ",
        help="publish /tf at most this often (default 0: every tick)",
    )


def run(args: argparse.Namespace) -> int:
    host, port = parse_listen(args.listen, "foxglove", DEFAULT_LISTEN)
    if args.tf_rate < 0:
        raise ConfigError(f"--tf-rate {args.tf_rate} must be >= 0 (0 = every tick)")
    from clients.foxglove.bridge import Bridge
    from clients.robot import Robot

    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    creds = credentials_from_args(args)
    with Robot(args.connect, args.robot, name="foxglove", credentials=creds) as robot:
        robot.check_protocol(3.0)
        try:
            bridge = Bridge(robot, host, port, args.tf_rate)
        except RuntimeError as exc:
            raise ConfigError(
                f"cannot serve Foxglove on {host}:{port}: {exc}; choose another --listen"
            ) from None
        try:
            print(f"foxglove: ws://{host}:{bridge.port}", flush=True)
            stop.wait()
        finally:
            bridge.close()
    return 0
