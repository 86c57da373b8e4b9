"""`darwin certs`: a CA, the robot's certificate and client certificates for TLS.

    darwin certs --host 10.0.0.5 --host op1.local --client alice --client bob

prints each file as ``name: path``. The CA is made once and kept; the robot certificate is
(re)made when ``--host`` is given or it does not exist yet; a client certificate's common name is
the user name, which access control matches like a login.
"""

from __future__ import annotations

import argparse
import socket
import sys
from pathlib import Path

from robot_daemon.security import certs
from robot_daemon.security.acl import default_certs_dir
from robot_daemon.security.users import check_name


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--dir", help=f"where the files go (default {default_certs_dir()})")
    parser.add_argument(
        "--host", action="append", default=[], metavar="ADDRESS",
        help="an address clients dial the robot (or router) at, repeatable; the certificate is "
        "valid for these (default: 127.0.0.1, localhost and this machine's name)",
    )
    parser.add_argument(
        "--client", action="append", default=[], metavar="USER",
        help="make a client certificate whose common name is USER, repeatable",
    )


def run(args: argparse.Namespace) -> int:
    directory = Path(args.dir) if args.dir else default_certs_dir()
    try:
        for name in args.client:
            check_name(name)
    except ValueError as exc:
        print(f"darwin certs: {exc}", file=sys.stderr)
        return 2
    ca = certs.create_ca(directory)
    print(f"ca: {ca.cert}")
    robot = certs.robot_paths(directory)
    if args.host or not robot.cert.exists():
        hosts = args.host or ["127.0.0.1", "localhost", socket.gethostname()]
        certs.create_robot(directory, hosts)
        print(f"robot: {robot.cert} ({', '.join(hosts)})")
    else:
        print(f"robot: {robot.cert} (kept; --host to make it again)")
    for name in args.client:
        c = certs.create_client(directory, name)
        print(f"client {name}: {c.cert}")
        print(f"client {name} key: {c.key}")
    return 0
