"""`darwin daemon`: the robot daemon on a serial port (`--port`) or on the emulator (`--sim`).

Prints ``port: PATH`` and then ``zenoh: ENDPOINT`` (flushed) once it serves — with
``--router`` the router's endpoint first, where clients connect; SIGINT/SIGTERM stop it cleanly
(and the emulator it started).
"""

from __future__ import annotations

import argparse
import logging
import os
import shutil
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

from config.loader import load_all, robot_from_dict
from robot_daemon.emulator.options import add_forwarded_options
from robot_daemon.launch.children import Child, relay_to_stderr
from robot_daemon.launch.endpoints import check_login_needs_router, resolve_listen, router_of
from robot_daemon.security.options import (
    add_security_arguments,
    listen_warnings,
    secure_listen,
    security_from_args,
)
from schemas.errors import ConfigError
from schemas.keys import check_robot_name
from schemas.session import (
    add_credential_arguments,
    credential_env,
    credentials_from_args,
    free_tcp_port,
)
from schemas.signals import on_stop_signals

if TYPE_CHECKING:
    from robot_daemon.engine.daemon import Daemon
    from robot_daemon.engine.fleet_join import RouterWatch

log = logging.getLogger(__name__)

# The emulator answers from a Python process that shares the CPU with everything else: a
# servo is called offline only after this many missed ticks in a row (200 ms), so a busy
# machine costs a stale reading, not a lost servo (the reply margin: bus.sim_reply_margin_ms).
SIM_OFFLINE_AFTER = 25


def add_arguments(parser: argparse.ArgumentParser) -> None:
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--port", help="serial port of the CM-730 (config daemon.port)")
    where.add_argument(
        "--sim", action="store_true", help="start the emulator (`darwin sim`) and use its pty"
    )
    parser.add_argument("--robot", help="robot name in every key (config robot.name)")
    parser.add_argument(
        "--listen",
        action="append",
        help="Zenoh endpoint to listen on, repeatable (config zenoh.listen); port 0 = any free",
    )
    parser.add_argument(
        "--router",
        metavar="ENDPOINT",
        help="join this Zenoh router (`darwin router`) instead of being the meeting point "
        "(config zenoh.router); listens only where --listen says",
    )
    parser.add_argument("--tick-ms", type=float, help="motion loop period (config daemon.tick_ms)")
    parser.add_argument(
        "--camera",
        help="none | sim | pattern | device index or path (default: sim with --sim, else "
        "config daemon.camera.source)",
    )
    parser.add_argument(
        "--allow-eeprom",
        action="store_true",
        default=None,
        help="let the `registers` verb write EEPROM (config daemon.allow_eeprom_writes)",
    )
    parser.add_argument(
        "--allow-hardware-writes",
        action="store_true",
        default=None,
        help="let the `registers` verb write power, IDs, baud rate and limits "
        "(config daemon.allow_hardware_writes)",
    )
    parser.add_argument("--config", help="user config file (TOML) on top of the shipped one")
    parser.add_argument(
        "--reply-margin-ms",
        type=float,
        help="time allowed for a reply beyond its wire time and return delay (config "
        "bus.reply_margin_ms, with --sim bus.sim_reply_margin_ms)",
    )
    add_forwarded_options(parser, "with --sim: ")
    add_security_arguments(parser)
    # Who this robot is to an authenticated router (`darwin users add NAME --role robot`).
    add_credential_arguments(parser)


def sim_command(sim_args: list[str], wire_timing: bool | None) -> list[str]:
    args = ["sim", *sim_args]
    if wire_timing is False:  # the emulator times the wire unless told not to
        args.append("--no-wire-timing")
    return args


def default_camera(args: argparse.Namespace, dcfg: dict[str, Any]) -> str:
    """On the emulator the simulated camera, so a first run shows everything (ball play, the
    Camera tab, ``robot.image()``); on a real port the config's choice (none unless set)."""
    if args.sim:
        return "sim"
    return str(dcfg.get("camera", {}).get("source", "none"))


def build(args: argparse.Namespace, port: str) -> tuple[Daemon, dict[str, Any]]:
    settings = load_all(args.config)
    try:
        return _build(args, port, settings), settings
    except (ValueError, TypeError) as exc:
        # Everything here reads the config: a value of the wrong kind is the file's fault.
        where = args.config or "the shipped config (config/*.toml, DARWIN_CONFIG)"
        raise ConfigError(
            f"a value in {where} is not usable: {exc}; fix it (the shipped files in config/ show "
            "each value's kind)"
        ) from None


def _build(args: argparse.Namespace, port: str, settings: dict[str, Any]) -> Daemon:
    from robot_daemon.engine.daemon import Daemon, DaemonOptions
    from robot_daemon.vision.sources import check_spec

    bus = settings.setdefault("bus", {})
    if args.reply_margin_ms is not None:
        bus["reply_margin_ms"] = args.reply_margin_ms
    elif args.sim:
        margin = bus.get("sim_reply_margin_ms", bus.get("reply_margin_ms", 1.5))
        bus["reply_margin_ms"] = float(margin)
    if args.sim:
        daemon_cfg = settings.setdefault("daemon", {})
        daemon_cfg["offline_after_misses"] = max(
            SIM_OFFLINE_AFTER, int(daemon_cfg.get("offline_after_misses", 0))
        )
    robot = robot_from_dict(settings["robot"])
    dcfg = settings.get("daemon", {})
    router = router_of(args, settings)
    try:
        name = check_robot_name(args.robot or robot.name)
        security = security_from_args(args)
        # Joined to a router, the daemon listens only where told: two robots on one machine
        # must not both want the shipped port.
        default_listen = [] if router else list(settings.get("zenoh", {}).get("listen", []))
        listen = secure_listen(args.listen or default_listen, security, explicit=bool(args.listen))
        listen = resolve_listen(listen)
        check_login_needs_router(args, router)
        creds = credentials_from_args(args) if router else None
    except (ValueError, OSError) as exc:  # a bad --robot, --listen, --mtls or login names itself
        raise ConfigError(str(exc)) from None
    for warning in listen_warnings(listen, security):
        print(f"darwin daemon: {warning}", file=sys.stderr, flush=True)
    camera = check_spec(args.camera or default_camera(args, dcfg))
    opts = DaemonOptions(
        robot=name,
        port=port,
        listen=listen,
        router=router,
        tick_ms=float(args.tick_ms or dcfg.get("tick_ms", 8.0)),
        camera=camera,
        allow_eeprom=bool(
            args.allow_eeprom
            if args.allow_eeprom is not None
            else dcfg.get("allow_eeprom_writes", False)
        ),
        security=security,
        credentials=creds,
        extras={
            "allow_hardware_writes": bool(
                args.allow_hardware_writes
                if args.allow_hardware_writes is not None
                else dcfg.get("allow_hardware_writes", False)
            )
        },
    )
    daemon = Daemon(opts, robot, settings)
    if args.sim:  # the emulator has no ROBOTIS config.ini to compare with
        return daemon
    # Here, not at the top: only a daemon on a real robot reads ROBOTIS's file.
    from config.robotis_offsets import ROBOTIS_CONFIG_INI, offsets_not_imported

    ini = str(dcfg.get("robotis_config_ini", ROBOTIS_CONFIG_INI) or "")
    missing = offsets_not_imported(ini, robot) if ini else None
    if missing is not None:
        log.warning("%s", missing.line())
        daemon.bus.config_warnings.append(missing.line())
    return daemon


def run(args: argparse.Namespace) -> int:
    emulator: Child | None = None
    private: str | None = None  # the emulator's control socket's directory, with access control
    connect: list[str] = []
    if args.sim:
        sim_args = list(args.sim_arg)
        settings = load_all(args.config)
        router = router_of(args, settings)
        robot_name = args.robot or settings["robot"].get("name", "op1")
        world = "--no-world" not in sim_args
        if router and world and not any(a.startswith("--world-connect") for a in sim_args):
            # In a fleet the world joins the router too, so every client of the router
            # reaches this robot's world and emulator control under its name; it logs in
            # with the robot's identity (the emulator child reads it from the environment).
            sim_args += [f"--world-connect={router}", f"--robot={robot_name}"]
            private = tempfile.mkdtemp(prefix="darwin-sim-")
            os.environ.update(credential_env(credentials_from_args(args), Path(private)))
        elif not any(a.startswith("--control-listen") for a in sim_args):
            # The emulator's control ops (faults…) and world, reachable through the daemon.
            # With access control, over a Unix socket in a private directory: only this user
            # reaches it, and the daemon's rules give that link (only) every right.
            if args.auth or args.secure:
                private = tempfile.mkdtemp(prefix="darwin-sim-")
                control = f"unixsock-stream/{private}/control.sock"
            else:
                control = f"tcp/127.0.0.1:{free_tcp_port()}"
            sim_args += [f"--control-listen={control}", f"--robot={robot_name}"]
            connect.append(control)
        if not any(a.startswith("--link") for a in sim_args):
            # A stable path: when the emulator's port vanishes and comes back (a new pty),
            # the daemon reopens the same name.
            sim_args.append(f"--link={tempfile.gettempdir()}/darwin-sim-{os.getpid()}.tty")
        # Ctrl-C must not stop the emulator under the daemon: the daemon halts and holds the
        # pose on it first, then stops it.
        emulator = Child(
            "sim", sim_command(sim_args, args.wire_timing), relay_to_stderr, own_group=True
        )
        # The engine (numpy, Zenoh, the motion modules) is imported here rather than at the top,
        # so that it loads while the emulator starts rather than before.
        import robot_daemon.engine.daemon  # noqa: F401

        port = emulator.wait_line("port:", timeout=20.0)
    else:
        port = args.port or str(load_all(args.config).get("daemon", {}).get("port"))
    from robot_daemon.engine.fleet_join import RouterWatch

    daemon: Daemon | None = None
    watch: RouterWatch | None = None
    try:
        daemon, _ = build(args, port)
        daemon.options.connect = connect

        def on_signal(signum: int) -> None:
            log.info("signal %d: stopping", signum)
            daemon.stop()

        on_stop_signals(on_signal)
        # Fail fast on a wrong or busy port at start; later losses are reopened with back-off.
        daemon.connect_bus()
        if daemon.options.router:
            # Checked before the daemon's own session: unreachable or refused says so now.
            watch = RouterWatch(daemon.options.router, daemon.options.credentials)
            if daemon.options.security is not None:
                daemon.options.security.router_zids = watch.router_zids
        daemon.start_network()
        if watch is not None:
            watch.wait_visible(daemon.keys.alive)
            watch.watch(daemon.keys.alive)
        print(f"port: {port}", flush=True)
        print(f"robot: {daemon.options.robot}", flush=True)
        # Where clients connect: the router first (what `darwin up` passes on), then our own.
        routers = [daemon.options.router] if daemon.options.router else []
        for ep in [*routers, *daemon.options.listen]:
            print(f"zenoh: {ep}", flush=True)
        daemon.run()
        return 0
    finally:
        if watch is not None:
            watch.close()
        if daemon is not None:
            daemon.close()
        if emulator is not None:
            emulator.stop()
        if private is not None:
            shutil.rmtree(private, ignore_errors=True)
        sys.stdout.flush()
