"""``darwin sim``: the hardware emulator on a pseudo-terminal, with its world, until SIGINT/SIGTERM.

Prints one line ``port: <path>`` on stdout once the port accepts clients. With
``--control-listen ENDPOINT`` it also serves the control ops (faults, state, body motion…) on
``darwin/<robot>/sim/control``.

This module composes the two halves: the emulator (:mod:`robot_daemon.emulator`, which never
imports the plant) and the simulated world (:mod:`robot_daemon.plant.world_link`: its
``add_arguments(parser)`` adds options here and ``attach(emulator, args, session)`` is called
once the emulator runs, ``session`` being the control session or None, and returns a function
called at shutdown, or None with ``--no-world``).
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
import threading
from typing import Any

from robot_daemon.emulator.emulator import Emulator
from robot_daemon.emulator.options import add_physics_option
from robot_daemon.emulator.settings import EmulatorSettings
from robot_daemon.plant import world_link
from schemas.signals import on_stop_signals

log = logging.getLogger(__name__)


def _ids(text: str) -> list[int]:
    try:
        ids = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of IDs") from None
    if any(not 0 <= i <= 253 for i in ids):
        raise argparse.ArgumentTypeError(f"IDs in {text!r} must be 0..253")
    return ids


def _probability(text: str) -> float:
    try:
        p = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0.0 <= p <= 1.0:
        raise argparse.ArgumentTypeError(f"probability {p} is outside 0..1")
    return p


# The options that override one [emulator] setting each: (flag, field, metavar, type, help).
# A flag's field is what settings_from_args hands to EmulatorSettings.
_OVERRIDES: tuple[tuple[str, str, str, Any, str], ...] = (
    ("--seed", "seed", "N", int, "seed of every random draw (replays a run)"),
    ("--drop", "drop", "P", _probability, "probability of a dropped reply"),
    ("--corrupt", "corrupt", "P", _probability, "probability of a corrupted reply"),
    ("--delay", "delay", "P", _probability, "probability of a delayed reply"),
    ("--delay-ms", "delay_ms", "MS", float, "how late a delayed reply is (ms)"),
    (
        "--ftdi-latency-ms",
        "ftdi_latency_ms",
        "MS",
        float,
        "deliver replies as an FTDI chip: 62-byte USB packets, the rest after this latency "
        "timer (default 1, as the robot's adapter is set; 0: each reply as it completes)",
    ),
    ("--silent-ids", "silent_ids", "IDS", _ids, "IDs that never answer, e.g. 7,8"),
    ("--overheat", "overheat_ids", "IDS", _ids, "servo IDs stuck above their limit"),
    (
        "--broken-after",
        "broken_after",
        "IDS",
        _ids,
        "a cable break right after each of these servos, e.g. 11 (hides 13, 15, 17)",
    ),
    (
        "--fresh-servo",
        "fresh_servo",
        "ID",
        int,
        "swap this servo for a factory-fresh MX-28 (ID 1, 57,600 bps)",
    ),
    (
        "--cm730-late-reads",
        "cm730_late_reads",
        "N",
        int,
        "the CM-730 ignores the first N reads and bulk reads",
    ),
    ("--old-firmware-ids", "old_firmware_ids", "IDS", _ids, "servos with MX-28 firmware 26"),
    ("--leftover-ram-ids", "leftover_ram_ids", "IDS", _ids, "servos with slow leftover RAM"),
    ("--sag-units", "sag_units", "UNITS", float, "loaded servos stand this far off (P=32)"),
    ("--voltage", "voltage", "V", float, "supply voltage (V)"),
    ("--imu-noise", "imu_noise", "COUNTS", float, "IMU noise, standard deviation in counts"),
    (
        "--power-on-delay",
        "power_on_delay_s",
        "S",
        float,
        "servos answer this long after DXL_POWER is set (s)",
    ),
    (
        "--realtime-priority",
        "realtime_priority",
        "N",
        int,
        "SCHED_FIFO priority of the serving thread, 1..99 (0: normal scheduling)",
    ),
    ("--link", "link", "PATH", str, "keep a symlink to the pty at this path (stable port path)"),
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--config", metavar="FILE", help="user config file (its [emulator] section)"
    )
    parser.add_argument(
        "--no-wire-timing",
        dest="wire_timing",
        action="store_false",
        default=None,
        help="answer at once instead of at 1 Mbps wire speed",
    )
    for flag, dest, metavar, kind, text in _OVERRIDES:
        parser.add_argument(flag, dest=dest, metavar=metavar, type=kind, help=text)
    add_physics_option(parser, "the plant behind the servos")
    parser.add_argument(
        "--control-listen", metavar="ENDPOINT", help="Zenoh endpoint for the control ops"
    )
    parser.add_argument(
        "--robot", metavar="NAME", help="robot name in the control key (default op1)"
    )
    world_link.add_arguments(parser)


def settings_from_args(args: argparse.Namespace) -> EmulatorSettings:
    names = ("wire_timing", "physics", *(dest for _, dest, *_ in _OVERRIDES))
    return EmulatorSettings.load(args.config, **{n: getattr(args, n) for n in names})


def run(args: argparse.Namespace) -> int:
    settings = settings_from_args(args)
    if settings.physics == "mujoco":
        from robot_daemon.plant.physics.mujoco_world import import_mujoco

        try:
            import_mujoco()
        except RuntimeError as exc:
            print(f"darwin sim: {exc}", file=sys.stderr)
            return 2
    stop = threading.Event()
    on_stop_signals(lambda _signum: stop.set())
    closers = []
    with contextlib.ExitStack() as stack:
        try:
            emulator = stack.enter_context(Emulator(settings))
        except (KeyError, ValueError) as exc:
            message = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
            print(f"darwin sim: {message}", file=sys.stderr)
            return 2
        except OSError as exc:
            print(f"darwin sim: cannot create the port ({exc}); check --link", file=sys.stderr)
            return 2
        session = None
        if args.control_listen:
            from robot_daemon.emulator.control_service import serve_control
            from schemas.session import open_server, resolve

            target = resolve(args.control_listen, args.robot)
            session = open_server([target.endpoint])
            stack.callback(session.close)
            queryable = serve_control(session, target.robot, emulator)
            stack.callback(queryable.undeclare)
            log.info("sim control on %s (robot %s)", target.endpoint, target.robot)
        closer = world_link.attach(emulator, args, session)
        if closer is not None:
            closers.append(closer)
        print(f"port: {emulator.port}", flush=True)
        print(f"seed {emulator.seed} on {emulator.port}", file=sys.stderr, flush=True)
        # With a timeout: a signal the kernel hands to another thread (one arriving while an
        # earlier one is pending) must not leave the main thread blocked for ever.
        while not stop.wait(0.5):
            pass
        for closer in reversed(closers):
            closer()
    return 0
