"""`darwin up`: emulator (unless `--port`), daemon and gateway in one command.

Prints where each listens, one line each and flushed — ``zenoh: tcp/HOST:PORT`` and
``gateway: HOST:PORT`` (or ``gateway: none (…)``) — then relays the children's output until
Ctrl-C or SIGTERM, which stop every child (none is left behind).
"""

from __future__ import annotations

import argparse
import importlib.util
import signal
import subprocess
import sys
import threading

from config.loader import load_all
from robot_daemon.children import Child, ChildError, relay_to_stderr
from robot_daemon.daemon_cli import _resolve_listen

START_TIMEOUT = 30.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", help="robot name in every key (config robot.name)")
    parser.add_argument(
        "--listen", help="Zenoh endpoint of the daemon (config zenoh.listen); port 0 = any free"
    )
    parser.add_argument(
        "--gateway-listen", help="HOST:PORT of the legacy TCP gateway (config gateway.listen)"
    )
    parser.add_argument("--no-gateway", action="store_true", help="do not start the gateway")
    parser.add_argument("--port", help="a real robot's serial port instead of the emulator")
    parser.add_argument("--camera", help="none | sim | pattern | device (config daemon.camera)")
    parser.add_argument("--tick-ms", type=float, help="motion loop period")
    parser.add_argument("--allow-eeprom", action="store_true", help="allow EEPROM register writes")
    parser.add_argument("--config", help="user config file (TOML), passed to every child")
    parser.add_argument(
        "--sim-arg",
        action="append",
        default=[],
        metavar="ARG",
        help="extra emulator argument (repeatable), e.g. --sim-arg=--drop=0.05",
    )
    parser.add_argument(
        "--tui", action="store_true", help="open the terminal UI here once everything runs"
    )
    parser.add_argument(
        "--foxglove", action="store_true", help="also start the Foxglove server (darwin foxglove)"
    )
    parser.add_argument("--foxglove-listen", metavar="HOST:PORT", help="where Foxglove connects")
    parser.add_argument(
        "--web", action="store_true", help="also serve the terminal UI to browsers (darwin web)"
    )
    parser.add_argument("--web-listen", metavar="HOST:PORT", help="where browsers connect")
    parser.add_argument(
        "--wire-timing",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="model 1 Mbps wire time in the emulator",
    )


def gateway_available() -> bool:
    try:
        return importlib.util.find_spec("gateway.cli") is not None
    except ModuleNotFoundError:
        return False


def daemon_args(args: argparse.Namespace, listen: str) -> list[str]:
    out = ["daemon", "--listen", listen]
    if args.port:
        out += ["--port", args.port]
    else:
        out += ["--sim", *(f"--sim-arg={a}" for a in args.sim_arg)]
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
    return out


def run(args: argparse.Namespace) -> int:
    settings = load_all(args.config)
    listen = _resolve_listen(
        [args.listen or settings.get("zenoh", {}).get("listen", ["tcp/127.0.0.1:7447"])[0]]
    )[0]
    stop = threading.Event()

    def on_signal(_signum: int, _frame: object) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    children: list[Child] = []
    # With the UI in this terminal, the children's chatter would scribble over it.
    relay = None if args.tui else relay_to_stderr
    try:
        daemon = Child("daemon", daemon_args(args, listen), relay)
        children.append(daemon)
        endpoint = daemon.wait_line("zenoh:", START_TIMEOUT)
        robot = daemon_robot(daemon, args.robot or settings["robot"].get("name", "op1"))
        print(f"zenoh: {endpoint}", flush=True)
        print(f"robot: {robot}", flush=True)
        if args.no_gateway:
            print("gateway: none (--no-gateway)", flush=True)
        elif not gateway_available():
            print("gateway: none (not in this build)", flush=True)
        else:
            gw = ["gateway", "--connect", endpoint, "--robot", robot]
            gw_listen = args.gateway_listen or settings.get("gateway", {}).get("listen")
            if gw_listen:
                gw += ["--listen", gw_listen]
            if args.config:
                gw += ["--config", args.config]
            gateway = Child("gateway", gw, relay)
            children.append(gateway)
            print(f"gateway: {gateway.wait_line('gateway:', START_TIMEOUT)}", flush=True)
        for name, wanted, listen in (
            ("foxglove", args.foxglove, args.foxglove_listen),
            ("web", args.web, args.web_listen),
        ):
            if wanted:
                extra = ["--listen", listen] if listen else []
                child = Child(name, [name, "--connect", endpoint, "--robot", robot, *extra], relay)
                children.append(child)
                print(f"{name}: {child.wait_line(f'{name}:', START_TIMEOUT)}", flush=True)
        if args.tui:
            return run_tui(endpoint, robot)
        # Run until a signal, or until a child dies (then stop the others and say so).
        while not stop.wait(0.5):
            dead = [c for c in children if not c.running()]
            if dead:
                for c in dead:
                    print(
                        f"darwin up: {c.name} exited with {c.proc.returncode}; stopping",
                        file=sys.stderr,
                        flush=True,
                    )
                return 1
        return 0
    except ChildError as exc:
        print(f"darwin up: {exc}", file=sys.stderr, flush=True)
        return 1
    finally:
        for c in reversed(children):
            c.stop()


def daemon_robot(daemon: Child, default: str) -> str:
    """The robot name the daemon printed (before its ``zenoh:`` line)."""
    for line in daemon.output:
        if line.startswith("robot:"):
            return line.split(":", 1)[1].strip()
    return default


def run_tui(endpoint: str, robot: str) -> int:
    """The terminal UI in the foreground; everything stops when it exits."""
    cmd = [sys.executable, "-m", "robot_daemon.cli", "tui", "--connect", endpoint, "--robot", robot]
    # The UI handles Ctrl-C itself; this process waits for it instead of dying first.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return subprocess.call(cmd)
