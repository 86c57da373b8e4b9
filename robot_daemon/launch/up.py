"""`darwin up`: emulator (unless `--port`), daemon and adapters in one command.

With ``--router ENDPOINT`` the robot joins a fleet: the daemon, the simulated world and the
adapters connect to that router (``zenoh:`` is then the router's endpoint) and the servers take
free ports unless told, so several ``darwin up --robot NAME`` share one machine.

Prints where each listens, one line each and flushed — ``zenoh: tcp/HOST:PORT`` and
``gateway: HOST:PORT`` (or ``gateway: none (…)``) — then relays the children's output until
Ctrl-C or SIGTERM, which stop every child (none is left behind; if this process is killed
outright, the children end themselves, see ``children.py``).

The daemon is the robot; the gateway, ros2, foxglove and web programs are adapters, which their
packages declare (:class:`schemas.registry.Adapter`: each gets ``--NAME`` or, started by default,
``--no-NAME``, and ``--NAME-listen`` when it serves a port); this module names none of them. An
adapter that dies is reported on one line and started again (with back-off); it never takes the
robot down. If the daemon dies, everything stops.
"""

from __future__ import annotations

import argparse
import importlib.util
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from config.loader import load_all
from robot_daemon.emulator.options import add_forwarded_options, add_physics_option
from robot_daemon.launch.adapter_logins import Login, adapter_login, names, roles, ui_login
from robot_daemon.launch.children import Child, ChildError, relay_to_stderr
from robot_daemon.launch.endpoints import check_login_needs_router, resolve_listen, router_of
from robot_daemon.security.acl import check_listen
from robot_daemon.security.options import (
    add_security_arguments,
    secure_listen,
    security_from_args,
)
from robot_daemon.security.paths import ca_paths
from schemas import registry
from schemas.errors import ConfigError
from schemas.roles import LADDER, Role
from schemas.session import add_credential_arguments, credential_args
from schemas.signals import on_stop_signals

if TYPE_CHECKING:
    from robot_daemon.security.internal import Internal

START_TIMEOUT = 30.0
RESTART_BACKOFF_MIN = 1.0  # s before an adapter that died is started again, doubling …
RESTART_BACKOFF_MAX = 30.0  # … up to this


@dataclass
class Adapter:
    """A child that serves the robot to some kind of client (gateway, ros2, web…)."""

    child: Child
    backoff: float = RESTART_BACKOFF_MIN
    restart_at: float | None = None  # when it is due to start again after dying
    started: float = field(default_factory=time.monotonic)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", help="robot name in every key (config robot.name)")
    parser.add_argument(
        "--listen", help="Zenoh endpoint of the daemon (config zenoh.listen); port 0 = any free"
    )
    parser.add_argument(
        "--router",
        metavar="ENDPOINT",
        help="join this Zenoh router (`darwin router`) instead of being the meeting point: the "
        "daemon, world and adapters connect there, servers pick free ports unless told "
        "(config zenoh.router)",
    )
    parser.add_argument("--port", help="a real robot's serial port instead of the emulator")
    parser.add_argument(
        "--camera",
        help="none | sim | pattern | device index or path (default: sim on the emulator; with "
        "--port, config daemon.camera.source)",
    )
    parser.add_argument("--tick-ms", type=float, help="motion loop period")
    parser.add_argument("--allow-eeprom", action="store_true", help="allow EEPROM register writes")
    parser.add_argument(
        "--allow-hardware-writes",
        action="store_true",
        help="allow register writes that can disable or lose hardware (power, IDs, limits)",
    )
    parser.add_argument("--config", help="user config file (TOML), passed to every child")
    add_forwarded_options(parser)
    add_physics_option(parser, "the emulator's plant")
    for adapter in registry.adapters():
        flag = f"--no-{adapter.name}" if adapter.default else f"--{adapter.name}"
        parser.add_argument(flag, action="store_true", help=adapter.help)
        if adapter.listen_help:
            parser.add_argument(
                f"--{adapter.name}-listen", metavar="HOST:PORT", help=adapter.listen_help
            )
    add_security_arguments(parser)
    add_credential_arguments(parser)  # with --router: who this robot is (not its adapters)
    parser.add_argument(
        "--adapter-role",
        action="append",
        metavar="[NAME=]ROLE",
        help=f"the role of the adapters started here ({', '.join(names())}; ROLE: "
        f"{', '.join(LADDER)}): one for all, or NAME=ROLE for one, repeatable (default: "
        "[adapters.NAME] role, operator); with --auth/--secure each logs in as darwin-NAME",
    )


def available(name: str) -> bool:
    """Whether ``darwin NAME``'s module is in this build."""
    module = registry_module(name)
    try:
        return module is not None and importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:
        return False


def registry_module(name: str) -> str | None:
    return next((c.module for c in registry.commands() if c.name == name), None)


def wanted(args: argparse.Namespace, adapter: registry.Adapter) -> bool:
    """Whether this run starts it: --NAME, or (started by default) no --no-NAME."""
    attr = adapter.name.replace("-", "_")
    return not getattr(args, f"no_{attr}") if adapter.default else getattr(args, attr)


def setting(settings: dict[str, Any], dotted: str | None) -> str | None:
    """A config value by its ``section.key`` (None when absent or unnamed)."""
    if dotted is None:
        return None
    section, _, key = dotted.rpartition(".")
    value = settings.get(section, {}).get(key)
    return str(value) if value else None


def daemon_args(
    args: argparse.Namespace, listen: str | None, router: str | None, internal: Internal | None
) -> list[str]:
    out = ["daemon"]
    if listen:
        out += ["--listen", listen]
    if router:
        out += ["--router", router, *credential_args(args)]
    if internal is not None:
        sec = internal.security
        out += ["--auth", str(internal.users_file()), "--certs", str(sec.certs_dir.resolve())]
        out += ["--secure"] if sec.tls else []
        out += ["--mtls"] if sec.mtls else []
    if args.port:
        out += ["--port", args.port]
    else:
        out += ["--sim", *(f"--sim-arg={a}" for a in args.sim_arg)]
        if args.physics:
            out.append(f"--sim-arg=--physics={args.physics}")
        if args.wire_timing is not None:
            out.append("--wire-timing" if args.wire_timing else "--no-wire-timing")
    for opt in ("robot", "camera", "config"):
        value = getattr(args, opt)
        if value:
            out += [f"--{opt}", value]
    if args.tick_ms:
        out += ["--tick-ms", str(args.tick_ms)]
    if args.allow_eeprom:
        out.append("--allow-eeprom")
    if args.allow_hardware_writes:
        out.append("--allow-hardware-writes")
    return out


def _physics_problem(args: argparse.Namespace) -> str | None:
    """Why ``--physics`` cannot run, as one line naming the fix, or None."""
    if args.physics is None:
        return None
    if args.port:
        return "--physics chooses the emulator's plant; it does not apply with --port"
    if args.physics == "mujoco":
        from robot_daemon.plant.physics.mujoco_world import import_mujoco

        try:
            import_mujoco()
        except RuntimeError as exc:
            return str(exc)
    return None


def run(args: argparse.Namespace) -> int:
    problem = _physics_problem(args)
    if problem:
        print(f"darwin up: {problem}", file=sys.stderr)
        return 2
    settings = load_all(args.config)
    router = router_of(args, settings)
    listen: str | None = None
    try:
        check_login_needs_router(args, router)
        security = security_from_args(args)
        if args.listen or not router:
            # Joined to a router, the daemon listens only where told (see `darwin daemon`).
            default_listen = settings.get("zenoh", {}).get("listen", ["tcp/127.0.0.1:7447"])[0]
            wanted_listen = [args.listen or default_listen]
            listen = resolve_listen(secure_listen(wanted_listen, security, bool(args.listen)))[0]
            check_listen([listen], security)  # a tcp/ endpoint under --secure, before anything
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    adapter_roles = roles(settings, args.adapter_role)  # a bad role fails before anything runs
    internal = None
    if security is not None:
        # Loaded only here: the internal identities exist only with --auth/--secure, and their
        # module (secrets, the identities' writer) costs every other start ~6 ms of CPU.
        from robot_daemon.security.internal import Internal

        internal = Internal(security)
    try:
        return _run(args, settings, listen, router, internal, adapter_roles)
    finally:
        if internal is not None:
            internal.close()


def _run(
    args: argparse.Namespace,
    settings: dict[str, Any],
    listen: str | None,
    router: str | None,
    internal: Internal | None,
    adapter_roles: dict[str, Role],
) -> int:
    servers = [a for a in registry.adapters() if not a.ui]
    ui_adapter = next((a for a in registry.adapters() if a.ui and wanted(args, a)), None)
    # Identities first: the daemon's merged identities file must list every adapter.
    logins = {
        a.name: adapter_login(a.name, adapter_roles[a.name], settings, args, router, internal)
        for a in servers
    }
    ui = None
    if ui_adapter is not None:
        name = ui_adapter.name
        ui = ui_login(name, adapter_roles[name], settings, args, router, internal)
    if ui is not None and ui.refused:
        say(ui.refused)
        return 2
    # In a fleet several `darwin up` share a machine: their servers take free ports unless
    # told otherwise (each prints where it listens).
    free = "127.0.0.1:0" if router else None
    stop = threading.Event()
    on_stop_signals(lambda _signum: stop.set())
    children: list[Child] = []
    adapters: list[Adapter] = []
    # With the UI in this terminal, the children's chatter would scribble over it.
    relay = None if ui is not None else relay_to_stderr
    try:
        daemon = Child("daemon", daemon_args(args, listen, router, internal), relay)
        children.append(daemon)
        # The adapters start now, held before they connect (Child(held=True)): their imports
        # overlap the daemon's start instead of following it. They are told where the daemon
        # will be, which `darwin up` chose: the router, else the listen endpoint it resolved.
        guess = (router or listen or "", args.robot or settings["robot"].get("name", "op1"))
        plan = adapter_plan(args, settings, servers, logins, free)
        held = {
            p.name: Child(p.name, p.command(*guess), relay, env=p.env, held=True)
            for p in plan
            if p.command is not None
        }
        children.extend(held.values())
        endpoint = daemon.wait_line("zenoh:", START_TIMEOUT)
        robot = daemon_robot(daemon, guess[1])
        print(f"zenoh: {endpoint}", flush=True)
        print(f"robot: {robot}", flush=True)
        for p in plan:
            name = p.name
            if p.command is None:
                print(f"{name}: none ({p.why_not})", flush=True)
                continue
            child = held.pop(name)
            if (endpoint, robot) == guess:
                child.go()
            else:  # not where it was told: start it afresh, told the daemon's own words
                child.stop()
                children.remove(child)
                child = Child(name, p.command(endpoint, robot), relay, env=p.env)
                children.append(child)
            adapters.append(Adapter(child))
            print(f"{name}: {child.wait_line(f'{name}:', START_TIMEOUT)}", flush=True)
        if ui is not None and ui_adapter is not None:
            # The UI is a person (adapter_logins.ui_login), never the robot; under --secure it
            # trusts the installation's CA unless told otherwise.
            ui_args = list(ui.args)
            if internal is not None and internal.security.tls and "--ca" not in ui_args:
                ui_args += ["--ca", str(ca_paths(internal.security.certs_dir).cert)]
            return run_tui(endpoint, robot, ui_args, ui.env(), ui_adapter.name)
        # Run until a signal or the daemon's death; adapters that die are started again.
        while not stop.wait(0.5):
            if not daemon.running():
                say(f"the daemon exited with {daemon.proc.returncode}; stopping")
                return 1
            for running in adapters:
                tend(running, children, relay)
        return 0
    except ChildError as exc:
        print(f"darwin up: {exc}", file=sys.stderr, flush=True)
        return 1
    finally:
        for c in reversed(children):
            c.stop()


@dataclass
class Planned:
    """A server adapter this run starts (``command`` of the daemon's endpoint and robot name,
    in ``env``), or names on a line ``NAME: none (why_not)`` (``command`` None)."""

    name: str
    command: Callable[[str, str], list[str]] | None = None
    env: dict[str, str] | None = None
    why_not: str = ""


def adapter_plan(
    args: argparse.Namespace,
    settings: dict[str, Any],
    servers: list[registry.Adapter],
    logins: dict[str, Login],
    free: str | None,
) -> list[Planned]:
    """The server adapters in order, each started or said not to be (an adapter off by default
    and not asked for is left out: it gets no line)."""
    plan: list[Planned] = []
    for adapter in servers:
        name, login = adapter.name, logins[adapter.name]
        if not wanted(args, adapter):
            if adapter.default:
                plan.append(Planned(name, why_not=f"--no-{name}"))
            continue
        if not available(name):
            plan.append(Planned(name, why_not="not in this build"))
            continue
        if login.refused:
            plan.append(Planned(name, why_not=login.refused))
            continue
        tail = [*login.args]
        if adapter.pass_role:
            tail += ["--role", str(login.role)]  # at most its role, whoever it is
        if adapter.listen_help:
            where = getattr(args, f"{name.replace('-', '_')}_listen")
            where = where or free or setting(settings, adapter.listen_setting)
            tail += ["--listen", where] if where else []
        if adapter.pass_config and args.config:
            tail += ["--config", args.config]

        def command(
            endpoint: str, robot: str, name: str = name, tail: list[str] = tail
        ) -> list[str]:
            return [name, "--connect", endpoint, "--robot", robot, *tail]

        plan.append(Planned(name, command, login.env()))
    return plan


def say(line: str) -> None:
    print(f"darwin up: {line}", file=sys.stderr, flush=True)


def tend(adapter: Adapter, children: list[Child], relay: Callable[[str, str], None] | None) -> None:
    """Report an adapter that died and start it again when its back-off is over."""
    child, now = adapter.child, time.monotonic()
    if adapter.restart_at is None:
        if child.running():
            if now - adapter.started > RESTART_BACKOFF_MAX:
                adapter.backoff = RESTART_BACKOFF_MIN  # it stayed up: a later crash starts afresh
            return
        adapter.restart_at = now + adapter.backoff
        say(
            f"{child.name} exited with {child.proc.returncode}; the robot keeps running; "
            f"starting {child.name} again in {adapter.backoff:.0f} s"
        )
        adapter.backoff = min(adapter.backoff * 2, RESTART_BACKOFF_MAX)
        return
    if now < adapter.restart_at:
        return
    adapter.restart_at = None
    child.stop()  # already gone: this lets go of its pipe
    children.remove(child)
    adapter.child = Child(child.name, child.args, relay, ready=True, env=child.env)
    adapter.started = now
    children.append(adapter.child)


def daemon_robot(daemon: Child, default: str) -> str:
    """The robot name the daemon printed (before its ``zenoh:`` line)."""
    for line in daemon.output:
        if line.startswith("robot:"):
            return line.split(":", 1)[1].strip()
    return default


def run_tui(
    endpoint: str,
    robot: str,
    login: list[str] | None = None,
    env: dict[str, str] | None = None,
    command: str = "tui",
) -> int:
    """The UI (``darwin COMMAND``) in the foreground; everything stops when it exits."""
    cmd = [
        sys.executable,
        "-m",
        "robot_daemon.launch.cli",
        command,
        "--connect",
        endpoint,
        "--robot",
        robot,
    ]
    cmd += login or []
    # The UI handles Ctrl-C itself; this process waits for it instead of dying first.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return subprocess.call(cmd, env=env)
