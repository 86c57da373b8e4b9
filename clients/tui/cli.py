"""``darwin tui``: the terminal UI, over SSH or locally."""

from __future__ import annotations

import argparse

from clients.tui import i18n
from schemas.errors import ConfigError, RobotUnreachableError
from schemas.session import Credentials, add_target_arguments, credentials_from_args


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_target_arguments(parser, robot_default="remembered, ")
    parser.add_argument("--name", help="your name, shown to others as the lease holder")
    parser.add_argument(
        "--lang",
        choices=i18n.available(),
        help="language of the interface (default: remembered, then your locale)",
    )
    parser.add_argument(
        "--ask", action="store_true", help="open the connect screen first to choose the robot"
    )


def check_reachable(endpoint: str, creds: Credentials | None = None) -> None:
    """Raise ``RobotUnreachableError`` (one line: cause and fix) if nothing listens there."""
    from schemas.session import check_endpoint, client_config, open_session

    try:
        check_endpoint(endpoint)
    except ValueError as exc:
        raise RobotUnreachableError(f"{exc}; pass e.g. --connect tcp/127.0.0.1:7447") from None
    session = open_session(
        client_config(endpoint, creds=creds),
        f"no daemon at {endpoint}: nothing answers there",
        "is `darwin up` running? Start it, or pass the address it printed (`zenoh: …`) "
        "with --connect",
    )
    session.close()


def run(args: argparse.Namespace) -> int:
    from clients.tui.app import DarwinApp

    try:
        creds = credentials_from_args(args)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    if args.connect and not args.ask:
        # Named on the command line: a wrong address is a one-line error, not a UI that waits.
        check_reachable(args.connect, creds)

    app = DarwinApp(
        endpoint=args.connect,
        robot=args.robot,
        name=args.name,
        lang=args.lang,
        ask=args.ask,
        credentials=creds,
    )
    app.run()
    return int(app.return_code or 0)
