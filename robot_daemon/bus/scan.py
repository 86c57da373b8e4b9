"""`darwin scan --port …`: every device on the bus with ID, model, firmware and key registers
(the robot's dxl_monitor). Opens the port exclusively, so it refuses while a daemon runs."""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from config.loader import load_all
from robot_daemon.bus.dxl import DxlBus, error_names
from robot_daemon.bus.port import BlockingPortHandler, latency_timer_ms
from robot_daemon.bus.tables import CM730, CM730_ID, CM730_MODEL, MX28, MX28_MODEL
from schemas import units
from schemas.errors import BusError, PortError

MODELS = {MX28_MODEL: "MX-28", CM730_MODEL: "CM-730"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", help="serial port (config daemon.port)")
    parser.add_argument("--baud", type=int, default=None, help="baud rate (config daemon.baud)")
    parser.add_argument(
        "--ids", default="1-20,200", help="IDs to ask, e.g. 1-20,200 (default) or 0-253"
    )
    parser.add_argument(
        "--tries",
        type=int,
        default=3,
        help="times each ID is asked before it counts as absent (default 3)",
    )
    parser.add_argument("--no-power", action="store_true", help="do not power the servo bus")
    parser.add_argument("--json", action="store_true", help="one JSON object per device")
    parser.add_argument(
        "--fix-return-delay", action="store_true", help="set every return delay to 0 (EEPROM)"
    )
    parser.add_argument("--config", help="user config file")


def parse_ids(text: str) -> list[int]:
    ids: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        lo, _, hi = part.partition("-")
        try:
            a, b = int(lo), int(hi or lo)
        except ValueError:
            raise PortError(f"--ids {text!r}: {part!r} is not an ID or a range like 1-20") from None
        if not (0 <= a <= b <= 253):
            raise PortError(f"--ids {text!r}: {part!r} is outside 0..253")
        ids.extend(range(a, b + 1))
    return ids


def describe(bus: DxlBus, dxl_id: int, tries: int = 3) -> dict[str, Any] | None:
    """What ``dxl_id`` says of itself, or None if it never answers: one lost or garbled reply
    must not make a device look absent, so each read is tried ``tries`` times."""
    try:
        head, error = bus.read(dxl_id, 0, 6, tries=tries)
    except BusError:
        return None
    model = head[0] | head[1] << 8
    info: dict[str, Any] = {
        "id": dxl_id,
        "model": MODELS.get(model, f"{model:#06x}"),
        "firmware": head[2],
        "baud": 2_000_000 // (head[4] + 1),
        "return_delay_us": head[5] * 2,
        "alarms": error_names(error),
    }
    try:
        if model == CM730_MODEL:
            data, _ = bus.read(dxl_id, 24, 27, tries=tries)
            info.update(
                power=bool(data[0]),
                voltage=units.voltage_raw_to_v(data[CM730.VOLTAGE.reg.address - 24]),
                buttons=data[CM730.BUTTON.reg.address - 24],
            )
        else:
            data, _ = bus.read(dxl_id, 24, 20, tries=tries)

            def word(reg: MX28) -> int:
                o = reg.reg.address - 24
                return data[o] | data[o + 1] << 8

            info.update(
                torque=bool(data[0]),
                pid=[data[4], data[3], data[2]],
                position=word(MX28.PRESENT_POSITION),
                position_deg=round(units.raw_to_deg(word(MX28.PRESENT_POSITION)), 1),
                goal=word(MX28.GOAL_POSITION),
                voltage=units.voltage_raw_to_v(data[MX28.PRESENT_VOLTAGE.reg.address - 24]),
                temperature=data[MX28.PRESENT_TEMPERATURE.reg.address - 24],
            )
    except BusError as exc:
        info["error"] = str(exc)
    return info


def run(args: argparse.Namespace) -> int:
    if args.tries < 1:
        raise PortError(f"--tries must be at least 1, not {args.tries}")
    settings = load_all(args.config)
    dcfg = settings.get("daemon", {})
    port = args.port or dcfg.get("port", "/dev/ttyUSB0")
    margin = float(settings.get("bus", {}).get("reply_margin_ms", 4.0))
    handler = BlockingPortHandler(port, margin)
    handler.open(int(args.baud or dcfg.get("baud", 1_000_000)))
    try:
        bus = DxlBus(handler)
        if not args.no_power:
            try:
                bus.write(CM730_ID, CM730.DXL_POWER.reg.address, b"\x01", tries=args.tries)
                time.sleep(float(settings.get("bus", {}).get("power_on_delay_ms", 300)) / 1000)
            except BusError as exc:
                # stderr: with --json, stdout carries only the devices, one JSON object a line.
                print(
                    f"warning: could not power the servo bus through the CM-730: {exc}",
                    file=sys.stderr,
                )
        found = 0
        if not args.json:
            print(f"scanning {port} …")
        for dxl_id in parse_ids(args.ids):
            info = describe(bus, dxl_id, args.tries)
            if info is None:
                continue
            found += 1
            if args.fix_return_delay and info["return_delay_us"]:
                bus.write(dxl_id, MX28.RETURN_DELAY_TIME.reg.address, b"\x00", tries=args.tries)
                info["return_delay_us"] = 0
                info["fixed"] = "return delay set to 0"
            print(json.dumps(info) if args.json else format_line(info), flush=True)
        timer = latency_timer_ms(port)
        if not args.json:
            print(f"{found} device(s) answered on {port}")
            if timer is not None and timer > 1:
                print(
                    f"warning: USB latency timer is {timer} ms; set it to 1 (see README)",
                    file=sys.stderr,
                )
        return 0 if found else 1
    finally:
        handler.close()


def format_line(info: dict[str, Any]) -> str:
    extra = " ".join(
        f"{k}={v}" for k, v in info.items() if k not in ("id", "model", "firmware") and v != []
    )
    return f"ID {info['id']:3d}  {info['model']:<7} fw {info['firmware']:<3} {extra}"
