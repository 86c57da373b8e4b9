"""``darwin servo replace --id N``: give a new MX-28 (factory-fresh: ID 1 at 57,600 bps, or any
lone servo at any standard rate) servo N's place: its ID, the robot's baud rate, the return
delay and angle limits of ``[servo]``, firmware checked, EEPROM read back. Run it on the robot's
computer with the daemon stopped (the port must be free); it writes EEPROM, so it asks for the
ID again unless ``--yes`` is given. See docs/servo-replacement.md."""

from __future__ import annotations

import argparse
import sys

from config.loader import load_all, load_robot, section_to
from robot_daemon.bus.dxl import DxlBus, ReplyBudget
from robot_daemon.bus.port import BlockingPortHandler
from robot_daemon.bus.preflight import MIN_MX28_FIRMWARE
from robot_daemon.bus.replace import (
    ReplaceRefused,
    ServoSettings,
    check_free,
    choose,
    find_candidates,
    power_on,
    program,
)
from robot_daemon.bus.scan import parse_ids
from schemas.errors import PortInUseError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION")
    rep = sub.add_parser("replace", help="give a new servo the ID, baud rate and limits of one")
    rep.add_argument("--id", type=int, required=True, help="the ID the new servo takes (1..20)")
    rep.add_argument("--port", help="serial port (config daemon.port)")
    rep.add_argument("--config", metavar="FILE", help="user config file")
    rep.add_argument("--yes", action="store_true", help="do not ask for the ID again")
    rep.add_argument("--scan-ids", default="0-253", help="IDs a candidate may have (default 0-253)")
    rep.add_argument(
        "--margin-ms",
        type=float,
        default=5.0,
        help="reply margin of the search (ms); the writes use [bus] start_reply_margin_ms",
    )


def confirm(target: int, text: str) -> None:
    print(text, flush=True)
    print(f"type the ID ({target}) to write it, anything else to stop: ", end="", flush=True)
    answer = sys.stdin.readline().strip()
    if answer != str(target):
        raise ReplaceRefused(f"not confirmed (typed {answer!r}, not {target}); nothing written")


def run(args: argparse.Namespace) -> int:
    data = load_all(args.config)
    settings = section_to(ServoSettings, data.get("servo", {}), "servo")
    robot = load_robot(args.config)
    if args.id not in robot.by_id:
        raise ReplaceRefused(
            f"--id {args.id} is no joint of this robot (IDs {robot.ids[0]}..{robot.ids[-1]})"
        )
    dcfg, bus_cfg = data.get("daemon", {}), data.get("bus", {})
    port = args.port or dcfg.get("port", "/dev/ttyUSB0")
    baud = int(dcfg.get("baud", 1_000_000))
    handler = BlockingPortHandler(port)
    try:
        handler.open(baud)
    except PortInUseError as exc:
        raise ReplaceRefused(
            f"{exc}; stop the daemon first (Ctrl-C it, or stop its service)"
        ) from None
    try:
        # Generous while powering, checking and writing; short while asking 254 IDs at 7 rates.
        careful = float(bus_cfg.get("start_reply_margin_ms", 20.0))
        bus = DxlBus(handler, ReplyBudget(careful))

        def set_rate(bps: int) -> None:
            if not handler.setBaudRate(bps):
                raise ReplaceRefused(f"{port} cannot be set to {bps} bps")

        power_on(bus, handler.pause, float(bus_cfg.get("power_on_delay_ms", 300.0)) / 1000)
        check_free(bus, args.id)
        bus.budget.margin_ms = args.margin_ms
        found = find_candidates(bus, set_rate, baud, robot.ids, parse_ids(args.scan_ids))
        bus.budget.margin_ms = careful
        c = choose(found, args.id, MIN_MX28_FIRMWARE)
        joint = robot.joint(args.id)
        plan = (
            f"candidate: MX-28 firmware {c.firmware}, ID {c.id} at {c.baud} bps\n"
            f"plan: ID {c.id} → {args.id} ({joint.name}), {c.baud} → {baud} bps, return delay "
            f"{settings.return_delay_us} µs, angle limits {settings.cw_angle_limit}.."
            f"{settings.ccw_angle_limit}"
        )
        if args.yes:
            print(plan, flush=True)
        else:
            confirm(args.id, plan)
        got = program(bus, set_rate, c, args.id, baud, settings)
    finally:
        handler.close()
    print(
        f"servo {args.id}: ID {got['id']}, {got['baud']} bps, return delay "
        f"{got['return_delay_us']} µs, angle limits {got['cw_angle_limit']}.."
        f"{got['ccw_angle_limit']} (read back); start the daemon and run `darwin doctor`"
    )
    return 0
