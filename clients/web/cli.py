"""``darwin web``: the terminal UI in a browser.

Each browser tab runs its own ``darwin tui`` process (textual-serve starts one per websocket),
so every tab is an ordinary UI client of the key space with its own lease and settings.
Prints ``web: http://HOST:PORT`` once it serves, then runs until Ctrl-C or SIGTERM.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from clients.listen import add_server_arguments, parse_listen

DEFAULT_LISTEN = "127.0.0.1:8000"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_server_arguments(parser, DEFAULT_LISTEN, "browsers connect")
    parser.add_argument("--lang", help="language of the interface in every tab")


def tui_command(args: argparse.Namespace) -> str:
    """The shell command each tab runs: this interpreter's ``darwin tui``."""
    cmd = [sys.executable, "-m", "robot_daemon.launch.cli", "tui"]
    for opt in ("connect", "robot", "lang", "user", "password_file", "cert", "key", "ca"):
        value = getattr(args, opt, None)
        if value:
            # Files as absolute paths: each tab's program may start elsewhere.
            if opt in ("password_file", "cert", "key", "ca"):
                value = str(Path(value).resolve())
            cmd += [f"--{opt.replace('_', '-')}", value]
    return shlex.join(cmd)


def run(args: argparse.Namespace) -> int:
    from clients.web.server import serve
    from schemas.session import resolve_args

    host, port = parse_listen(args.listen, "web", DEFAULT_LISTEN)
    target = resolve_args(args)  # a bad endpoint, name or credential fails here, once
    serve(tui_command(args), host, port, title=f"darwin {target.robot}")
    return 0
