"""The `darwin` command. Each subcommand lives in its own module exposing
``add_arguments(parser)`` and ``run(args) -> int``; only the chosen one is imported. The
packages that bring commands declare them (:mod:`schemas.registry`): the robot's own in
:mod:`robot_daemon.launch.commands`, the gateway's and the clients' in their packages."""

from __future__ import annotations

import argparse
import errno
import importlib
import logging
import re
import sys
from types import ModuleType
from typing import Any

from robot_daemon.launch.child_side import wait_for_go, watch_parent
from schemas import registry
from schemas.errors import DarwinError
from schemas.extras import explain


def commands() -> dict[str, tuple[str, str]]:
    """name → (module, one-line help), by rank: every package declares its own commands
    (schemas.registry); this launcher names none of them. Also as ``cli.COMMANDS``."""
    return {c.name: (c.module, c.help) for c in registry.commands()}


def __getattr__(name: str) -> Any:
    # ``COMMANDS`` on demand: running one command does not list them all (see registry.find).
    if name == "COMMANDS":
        return commands()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _usage() -> str:
    listed = commands()
    width = max(map(len, listed))
    lines = ["usage: darwin COMMAND [options]   (darwin COMMAND --help for its options)", ""]
    lines += [f"  {name:<{width}}  {helptext}" for name, (_, helptext) in listed.items()]
    return "\n".join(lines)


def command_parser(name: str) -> tuple[ModuleType, argparse.ArgumentParser]:
    """The module of subcommand `name` and its argument parser (the docs' CLI reference and
    their command checks use the very parser `darwin NAME` runs)."""
    command = registry.find(name)
    if command is None:
        raise KeyError(name)
    module = importlib.import_module(command.module)
    parser = argparse.ArgumentParser(prog=f"darwin {name}", description=command.help)
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more logging")
    module.add_arguments(parser)
    return module, parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in {"-h", "--help", "help"}:
        print(_usage())
        return 0
    name = argv[0]
    command = registry.find(name)
    if command is None:
        print(f"darwin: unknown command {name!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    watch_parent()  # started by `darwin up`/`darwin daemon --sim`: end with that parent
    try:
        module, parser = command_parser(name)
    except ModuleNotFoundError as exc:
        if line := explain(exc):
            print(f"darwin {name}: {line}", file=sys.stderr)
            return 2
        if exc.name and command.module.startswith(exc.name):
            print(f"darwin {name}: not available in this build ({exc})", file=sys.stderr)
            return 2
        raise
    args = parser.parse_args(argv[1:])
    logging.basicConfig(
        level=logging.DEBUG
        if args.verbose > 1
        else logging.INFO
        if args.verbose
        else logging.WARNING,
        format="%(asctime)s %(name)s %(levelname)s: %(message)s",
        stream=sys.stderr,
    )
    if not wait_for_go():  # started held (children.Child) and then not wanted
        return 0
    try:
        return int(module.run(args) or 0)
    except DarwinError as exc:
        print(f"darwin {name}: {one_line(str(exc))}", file=sys.stderr)
        return 1
    except ModuleNotFoundError as exc:
        # An optional package imported only when a feature runs (a camera, certificates…).
        line = explain(exc)
        if line is None:
            raise
        print(f"darwin {name}: {line}", file=sys.stderr)
        return 2
    except OSError as exc:
        if exc.errno != errno.EADDRINUSE:
            raise
        print(
            f"darwin {name}: cannot listen: {exc.strerror or exc}; is another `darwin {name}` "
            "(or `darwin up`) running? Stop it, or choose another address with --listen "
            "(`darwin up --gateway-listen` for the gateway)",
            file=sys.stderr,
        )
        return 1
    except KeyboardInterrupt:
        return 130


# Zenoh's errors carry the Rust source file they came from; a user needs the sentence only.
_RUST_PLACE = re.compile(r"\s+at /\S+\.rs:\d+\.*")


def one_line(message: str) -> str:
    """An error message as the one line a program prints for an expected failure."""
    return " ".join(_RUST_PLACE.sub(".", message).split())


if __name__ == "__main__":
    sys.exit(main())
