"""``darwin gateway``: serve the legacy TCP JSON protocol to any number of clients.

Prints one line ``gateway: HOST:PORT`` once listening (port 0 becomes the real port), then logs
connects, disconnects and rejected input on stderr.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import signal

from gateway.server import Gateway
from gateway.settings import check_settings, load_settings
from schemas.roles import LADDER, parse_role
from schemas.session import add_target_arguments, resolve_args

# The limits a client cannot push past; each one a [gateway] setting of the same name.
LIMIT_OPTIONS: tuple[tuple[str, type, str, str], ...] = (
    ("--max-connections", int, "N", "clients at once; one more gets an error and is closed"),
    (
        "--idle-timeout",
        float,
        "S",
        "close a client that completes no message for S seconds (0 = never); one with monitor "
        "streams on may stay quiet, but must finish a message it starts within S",
    ),
    (
        "--max-partial-frame",
        int,
        "BYTES",
        "the most a client's message may announce, so the most held while it is incomplete",
    ),
    ("--max-depth", int, "N", "lists and objects nested in one message"),
    ("--max-number-length", int, "N", "characters of one number in a message"),
    (
        "--lease-idle-timeout",
        float,
        "S",
        "a client holding the control lease without a command for S seconds releases it",
    ),
)


def _limit_overrides(args: argparse.Namespace) -> dict[str, object]:
    names = (flag[2:].replace("-", "_") for flag, *_ in LIMIT_OPTIONS)
    return {name: getattr(args, name) for name in names}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_target_arguments(parser)
    parser.add_argument(
        "--listen",
        metavar="HOST:PORT",
        help="where legacy clients connect (default from [gateway] listen: 127.0.0.1:9000; "
        "port 0 picks a free one)",
    )
    parser.add_argument("--config", metavar="FILE", help="a user config file (TOML)")
    parser.add_argument(
        "--monitor-period", type=float, metavar="S", help="default monitoring period in seconds"
    )
    parser.add_argument(
        "--role",
        choices=[str(r) for r in LADDER],
        help="act as at most this role whatever the identity allows (observer: a watch-only "
        "gateway whose commands get an error reply); default: the identity's role",
    )
    limits = parser.add_argument_group("limits (defaults from [gateway] in config/gateway.toml)")
    for flag, kind, metavar, text in LIMIT_OPTIONS:
        limits.add_argument(flag, type=kind, metavar=metavar, help=text)


async def serve(args: argparse.Namespace) -> int:
    settings = load_settings(args.config).with_overrides(
        listen=args.listen, monitor_period=args.monitor_period, **_limit_overrides(args)
    )
    check_settings(settings)
    target = resolve_args(args)
    gateway = Gateway(settings, target)
    gateway.role = parse_role(args.role, people_only=True) if args.role else None
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    try:
        host, port = await gateway.start()
        print(f"gateway: {host}:{port}", flush=True)
        server = asyncio.create_task(gateway.serve_forever())
        await stop.wait()
        server.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await server
    finally:
        await gateway.close()
    return 0


def run(args: argparse.Namespace) -> int:
    if not args.verbose:
        # Connects, disconnects and (rate-limited) rejections are worth seeing by default.
        logging.getLogger("gateway").setLevel(logging.INFO)
    return asyncio.run(serve(args))
