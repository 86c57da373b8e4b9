"""The `darwin` command. Each subcommand lives in its own module exposing
``add_arguments(parser)`` and ``run(args) -> int``; only the chosen one is imported."""

from __future__ import annotations

import argparse
import errno
import importlib
import logging
import re
import sys
from types import ModuleType

from robot_daemon.children import watch_parent
from schemas.errors import DarwinError
from schemas.extras import explain

# name → (module, one-line help). Keep in the order a newcomer meets them.
COMMANDS: dict[str, tuple[str, str]] = {
    "up": ("robot_daemon.up", "start emulator (or --port), daemon and gateway in one command"),
    "daemon": (
        "robot_daemon.daemon_cli",
        "run the robot daemon (owns the bus, publishes, arbiter)",
    ),
    "router": ("robot_daemon.router", "a Zenoh router: the meeting point of a fleet of robots"),
    "list": ("clients.fleet_cli", "list every live robot (name, endpoint, lease, battery…)"),
    "sim": ("robot_daemon.plant.sim_cli", "run the hardware emulator on a pseudo-terminal"),
    "scan": ("robot_daemon.bus.scan", "list every device on a serial port (ID, model, firmware)"),
    "doctor": ("robot_daemon.doctor.cli", "check the robot: port, bus, servos, power, loop, Zenoh"),
    "calibrate": ("clients.calibrate_cli", "joint offsets: import ROBOTIS's config.ini offsets"),
    "servo": ("robot_daemon.servo_cli", "servo maintenance: give a new servo its ID and settings"),
    "gateway": ("gateway.cli", "serve the legacy TCP JSON protocol to any number of clients"),
    "tui": ("clients.tui.cli", "the terminal UI (works over SSH)"),
    "web": ("clients.web.cli", "serve the terminal UI to web browsers"),
    "foxglove": ("clients.foxglove.cli", "a Foxglove WebSocket server: 3D robot, camera, plots"),
    "motion": ("robot_daemon.motion.cli", "motion files: convert between .bin and text"),
    "record": ("clients.recording.record_cli", "record the robot's publications to MCAP"),
    "replay": ("clients.recording.replay_cli", "republish a recording on the key space"),
    "ros2": ("clients.ros2.cli", "make the robot a ROS 2 node (rmw_zenoh, no ROS install needed)"),
    "policy": ("clients.learn.runner", "run a policy (ONNX or Python) on the robot or simulator"),
    "urdf": ("clients.ros2.urdf_cli", "print the robot's URDF (from the body description)"),
    "users": ("robot_daemon.security.users_cli", "manage identities and roles (add/remove/list)"),
    "certs": ("robot_daemon.security.certs_cli", "create TLS certificates: CA, robot, clients"),
    "service": ("robot_daemon.service_cli", "start the daemon at boot: systemd units, udev rule"),
}


def _usage() -> str:
    width = max(map(len, COMMANDS))
    lines = ["usage: darwin COMMAND [options]   (darwin COMMAND --help for its options)", ""]
    lines += [f"  {name:<{width}}  {helptext}" for name, (_, helptext) in COMMANDS.items()]
    return "\n".join(lines)


def command_parser(name: str) -> tuple[ModuleType, argparse.ArgumentParser]:
    """The module of subcommand `name` and its argument parser (the docs' CLI reference and
    their command checks use the very parser `darwin NAME` runs)."""
    module_name, helptext = COMMANDS[name]
    module = importlib.import_module(module_name)
    parser = argparse.ArgumentParser(prog=f"darwin {name}", description=helptext)
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more logging")
    module.add_arguments(parser)
    return module, parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in {"-h", "--help", "help"}:
        print(_usage())
        return 0
    name = argv[0]
    if name not in COMMANDS:
        print(f"darwin: unknown command {name!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    watch_parent()  # started by `darwin up`/`darwin daemon --sim`: end with that parent
    try:
        module, parser = command_parser(name)
    except ModuleNotFoundError as exc:
        if line := explain(exc):
            print(f"darwin {name}: {line}", file=sys.stderr)
            return 2
        if exc.name and COMMANDS[name][0].startswith(exc.name):
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
