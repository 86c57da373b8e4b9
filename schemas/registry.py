"""Where ``darwin`` finds its subcommands and ``darwin up`` the adapters it can start.

Every package that brings commands declares them in a module of its own — a ``COMMANDS`` tuple
of :class:`Command` and, for programs ``darwin up`` may start next to the robot, an
``ADAPTERS`` tuple of :class:`Adapter` — and names that module as an entry point of the group
``darwin_zenoh.commands`` (``pyproject.toml``). The launcher (:mod:`robot_daemon.launch`)
reads them through this module only, so it names no adapter, and a package installed apart
(a plugin) adds its commands by declaring the same entry point.

An installation whose metadata predates the group (an editable install not yet refreshed)
falls back to :data:`BUILT_IN`, the same three modules ``pyproject.toml`` names. A provider
whose package is not in this build (a robot installed without the gateway) is skipped.

Nothing here imports a provider at import time; the provider modules import only this one.
Running one command (:func:`find`) reads no package metadata when the command is one of
:data:`BUILT_IN`'s: every ``darwin`` child of ``darwin up`` would otherwise pay for reading every
installed package's metadata at start-up.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from functools import cache
from types import ModuleType

GROUP = "darwin_zenoh.commands"
# The providers of this repository, in the order their commands are listed (pyproject.toml's
# entry points say the same; this is for metadata that has not got them yet).
BUILT_IN: tuple[str, ...] = (
    "robot_daemon.launch.commands",
    "gateway.commands",
    "clients.commands",
)


@dataclass(frozen=True)
class Command:
    """``darwin NAME``: its module exposes ``add_arguments(parser)`` and ``run(args) -> int``
    and is imported only when the command runs."""

    name: str
    module: str
    help: str
    rank: int  # `darwin --help` lists by rank: the order a newcomer meets the commands


@dataclass(frozen=True)
class Adapter:
    """A program ``darwin up`` starts next to the robot: the command of the same name, run as
    ``darwin NAME --connect ENDPOINT --robot ROBOT [its login] [--role R] [--listen HOST:PORT]
    [--config FILE]``, ready when it prints ``NAME: …``. It logs in as ``[adapters.NAME]``
    says (``config/adapters.toml``); one that dies is started again, the robot keeps running.
    """

    name: str
    help: str  # of `darwin up --NAME` (or, started by default, of `--no-NAME`)
    rank: int
    default: bool = False  # started unless --no-NAME (else only with --NAME)
    listen_help: str | None = None  # of `--NAME-listen HOST:PORT` (None: it serves no port)
    listen_setting: str | None = None  # "section.key" of its listen address in the config
    pass_role: bool = False  # told its role (it enforces at most that, whoever logs in)
    pass_config: bool = False  # given `darwin up --config`
    ui: bool = False  # the UI of `darwin up --tui`: runs in the foreground, not as a server


def providers() -> tuple[str, ...]:
    """The modules that declare commands: the entry points of :data:`GROUP`, else
    :data:`BUILT_IN`."""
    from importlib.metadata import entry_points  # reads every installed package's metadata

    found = tuple(ep.value.partition(":")[0] for ep in entry_points(group=GROUP))
    return found or BUILT_IN


def _provider(name: str) -> ModuleType | None:
    """The provider module ``name``; None when its package is not in this build."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name and name.startswith(exc.name):
            return None
        raise


@cache
def _loaded() -> tuple[tuple[Command, ...], tuple[Adapter, ...]]:
    commands: dict[str, Command] = {}
    adapters: dict[str, Adapter] = {}
    for name in providers():
        module = _provider(name)
        if module is None:
            continue  # that package is not in this build
        for command in getattr(module, "COMMANDS", ()):
            if command.name in commands:
                raise RuntimeError(f"{name} declares `darwin {command.name}` a second time")
            commands[command.name] = command
        for adapter in getattr(module, "ADAPTERS", ()):
            adapters[adapter.name] = adapter
    return (
        tuple(sorted(commands.values(), key=lambda c: c.rank)),
        tuple(sorted(adapters.values(), key=lambda a: a.rank)),
    )


def commands() -> tuple[Command, ...]:
    """Every ``darwin`` subcommand of this build, by rank."""
    return _loaded()[0]


def adapters() -> tuple[Adapter, ...]:
    """Every program ``darwin up`` can start next to the robot (the UI last), by rank."""
    return _loaded()[1]


def find(name: str) -> Command | None:
    """``darwin NAME``'s command, None when this build has none. One of :data:`BUILT_IN`'s is
    found in its provider alone (a plugin cannot take a built-in name: :func:`commands` refuses
    a name declared twice); any other name is looked up among every provider."""
    for provider in BUILT_IN:
        module = _provider(provider)
        declared: tuple[Command, ...] = getattr(module, "COMMANDS", ())
        found = next((c for c in declared if c.name == name), None)
        if found is not None:
            return found
    return next((c for c in commands() if c.name == name), None)
