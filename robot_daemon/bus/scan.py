"""`darwin scan --port …`: every device on the bus with ID, model, firmware and key registers
(the robot's dxl_monitor). Opens the port exclusively, so it refuses while a daemon runs."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from config.loader import load_all
from robot_daemon.bus.dxl import DxlBus, ReplyBudget, error_names
from robot_daemon.bus.port import BlockingPortHandler
from robot_daemon.bus.state import field_value
from robot_daemon.bus.tables import CM730, CM730_ID, CM730_MODEL, MX28, MX28_MODEL, Register
from schemas import units
from schemas.errors import BusError, PacketError, PortError

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


@dataclass(frozen=True)
class Identity:
    """What every device says of itself in its first registers."""

    model: int
    firmware: int
    baud: int  # the baud rate register (raw)
    return_delay: int  # the return delay register (raw, 2 µs units)
    error: int  # error bits of the reply
    cw_limit: int = 0  # the servo's own angle limits (raw; both 0 = wheel mode)
    ccw_limit: int = 4095


# Model number … return delay time: the same addresses on the MX-28 and the CM-730; then the
# MX-28's angle limits (the CM-730's registers there are read and ignored).
_IDENTITY_START = MX28.MODEL_NUMBER.reg.address
_IDENTITY_LENGTH = MX28.CCW_ANGLE_LIMIT.reg.end - _IDENTITY_START


def identity_warnings(ident: Identity, dxl_id: int, expected: int, port: str) -> list[str]:
    """What the daemon warns about a device found at start: a model other than expected, a
    return delay other than 0 (every reply waits that long), each naming the fix."""
    out = []
    if ident.model != expected:
        out.append(f"device {dxl_id} reports model {ident.model:#x}, expected {expected:#x}")
    if ident.return_delay != 0:
        delay_us = units.return_delay_s(ident.return_delay) * 1e6
        out.append(
            f"device {dxl_id} has return delay {ident.return_delay} ({delay_us:.0f} µs per "
            f"reply); set it to 0 (`darwin scan --port {port} --fix-return-delay`)"
        )
    return out


def identify(bus: DxlBus, dxl_id: int, tries: int = 3) -> Identity | None:
    """The identity of ``dxl_id``, or None if it never answers: one lost or garbled reply must
    not make a device look absent, so the read is tried ``tries`` times. A lost port raises."""
    try:
        head, error = bus.read(dxl_id, _IDENTITY_START, _IDENTITY_LENGTH, tries=tries)
    except PortError:
        raise
    except BusError:
        return None

    def at(reg: MX28) -> int:
        return field_value(head, _IDENTITY_START, reg.reg)

    return Identity(
        model=at(MX28.MODEL_NUMBER),
        firmware=at(MX28.FIRMWARE_VERSION),
        baud=at(MX28.BAUD_RATE),
        return_delay=at(MX28.RETURN_DELAY_TIME),
        error=error,
        cw_limit=at(MX28.CW_ANGLE_LIMIT),
        ccw_limit=at(MX28.CCW_ANGLE_LIMIT),
    )


# A collision garbles every read of differing data; noise now and then: this many in a row.
SHARED_ID_READS = 8


def shared_id(bus: DxlBus, dxl_id: int) -> bool:
    """Whether two servos answer ``dxl_id`` (a replaced or firmware-recovered servo given an ID
    in use; ROBOTIS: "identical ID … will cause communication collision"). Both answer every
    instruction at once: a ping's or an identity read's packets are the same from both and pass,
    while their present positions differ and arrive garbled every time. Noise garbles a reply
    now and then, so the position is read until one comes back whole: one read for a healthy
    servo; a shared ID never gives one in ``SHARED_ID_READS`` (a reply missed on a busy host
    proves nothing either way; a servo that only goes unanswered is absent, not shared). Two
    servos at the very same count are not told apart; they will not stay so once either moves.
    """
    garbled = 0
    for _ in range(SHARED_ID_READS):
        try:
            bus.read(dxl_id, MX28.PRESENT_POSITION.reg.address, 2, tries=1)
        except PacketError:
            garbled += 1
            continue
        except PortError:
            raise
        except BusError:
            continue
        return False
    return garbled >= 2


def _fields(
    bus: DxlBus, dxl_id: int, first: Register, last: Register, tries: int
) -> Callable[[Register], int]:
    """One read of ``first``..``last``; the returned function gives any register inside it."""
    data = bus.read(dxl_id, first.address, last.end - first.address, tries=tries)[0]
    return lambda reg: field_value(data, first.address, reg)


def describe(bus: DxlBus, dxl_id: int, tries: int = 3) -> dict[str, Any] | None:
    """What ``dxl_id`` says of itself (identity and key registers), or None if it never
    answers."""
    ident = identify(bus, dxl_id, tries)
    if ident is None:
        return None
    info: dict[str, Any] = {
        "id": dxl_id,
        "model": MODELS.get(ident.model, f"{ident.model:#06x}"),
        "firmware": ident.firmware,
        "baud": units.baud_register_to_bps(ident.baud),
        "return_delay_us": round(units.return_delay_s(ident.return_delay) * 1e6),
        "alarms": error_names(ident.error),
    }
    try:
        if ident.model == CM730_MODEL:
            read = _fields(bus, dxl_id, CM730.DXL_POWER.reg, CM730.VOLTAGE.reg, tries)

            def cm(reg: CM730) -> int:
                return read(reg.reg)

            info.update(
                power=bool(cm(CM730.DXL_POWER)),
                voltage=units.voltage_raw_to_v(cm(CM730.VOLTAGE)),
                buttons=cm(CM730.BUTTON),
            )
        else:
            read = _fields(bus, dxl_id, MX28.TORQUE_ENABLE.reg, MX28.PRESENT_TEMPERATURE.reg, tries)

            def mx(reg: MX28) -> int:
                return read(reg.reg)

            info.update(
                torque=bool(mx(MX28.TORQUE_ENABLE)),
                pid=[mx(MX28.P_GAIN), mx(MX28.I_GAIN), mx(MX28.D_GAIN)],
                position=mx(MX28.PRESENT_POSITION),
                position_deg=round(units.raw_to_deg(mx(MX28.PRESENT_POSITION)), 1),
                goal=mx(MX28.GOAL_POSITION),
                voltage=units.voltage_raw_to_v(mx(MX28.PRESENT_VOLTAGE)),
                temperature=mx(MX28.PRESENT_TEMPERATURE),
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
    bus_cfg = settings.get("bus", {})
    # A scan is not timed by any loop: the generous margin of the bus's start.
    margin = float(bus_cfg.get("start_reply_margin_ms", 20.0))
    handler = BlockingPortHandler(port)
    handler.open(int(args.baud or dcfg.get("baud", 1_000_000)))
    try:
        bus = DxlBus(handler, ReplyBudget(margin))
        if not args.no_power:
            try:
                bus.write(CM730_ID, CM730.DXL_POWER.reg.address, b"\x01", tries=args.tries)
                handler.pause(float(bus_cfg.get("power_on_delay_ms", 300)) / 1000)
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
        timer = handler.latency_timer_ms()
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
