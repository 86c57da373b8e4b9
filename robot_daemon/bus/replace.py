"""Servo replacement: give a new MX-28 its place on the robot, touching no other servo.

The e-manual's procedure for the DARwIn-OP: a new MX-28 comes as ID 1 at 57,600 bps; give it
its ID, set 1 Mbps, check its firmware, write the angle limits. Here: with the port free (the
daemon stopped), find exactly one candidate, a servo that answers at a standard baud rate other
than the robot's, or at the robot's rate under an ID the robot does not use, then write, to that
one servo only, the return delay, the angle limits, the ID and last the baud rate, and read its
EEPROM back at the robot's rate. Every write is addressed to the candidate's own ID at its own
rate, so no other servo hears one (they listen at the robot's rate, under other IDs).
"""

from __future__ import annotations

import contextlib
import struct
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from robot_daemon.bus.dxl import DxlBus
from robot_daemon.bus.scan import MODELS, identify
from robot_daemon.bus.tables import CM730, CM730_ID, MX28, MX28_MODEL, STANDARD_BAUDS
from schemas import units
from schemas.errors import BusError, DarwinError

# How long the read-back after the baud rate write keeps asking (s).
READBACK_S = 2.0
# How many times the baud rate write is sent when the servo stays at its old rate.
BAUD_WRITES = 3


class ReplaceRefused(DarwinError):
    """A replacement that would be unsafe or cannot be done; the message names the fix."""


@dataclass
class ServoSettings:
    """What a replaced servo is written besides its ID and baud rate: return delay and angle
    limits."""

    return_delay_us: int = 0
    cw_angle_limit: int = 0
    ccw_angle_limit: int = 4095


@dataclass(frozen=True)
class Candidate:
    """A servo that may be the new one: where it answered, and its model and firmware."""

    id: int
    baud: int
    model: int
    firmware: int


def baud_register(bps: int) -> int:
    """The baud rate register for ``bps`` (Protocol 1.0: bps = 2 M / (register + 1))."""
    return max(0, round(2_000_000 / bps) - 1)


SWEEPS = 2  # sweeps of every rate and ID while none answers


def find_candidates(
    bus: DxlBus,
    set_rate: Callable[[int], None],
    robot_baud: int,
    robot_ids: Iterable[int],
    scan_ids: Iterable[int],
) -> list[Candidate]:
    """Every servo that answers where none of the robot's should: at a standard rate other than
    ``robot_baud``, any ID; at ``robot_baud``, an ID that is not the robot's."""
    taken = {*robot_ids, CM730_ID}
    scan = list(scan_ids)
    found: list[Candidate] = []
    # One ping per ID and rate keeps the sweep short; a sweep that heard nothing is made once
    # more, since one lost reply (a noisy line, a busy computer: the emulator on a loaded host
    # answered a ping late) would otherwise read as "no new servo".
    for _sweep in range(SWEEPS):
        for rate in (57_600, *(b for b in STANDARD_BAUDS if b != 57_600)):
            set_rate(rate)
            for dxl_id in scan:
                if rate == robot_baud and dxl_id in taken:
                    continue
                ident = identify(bus, dxl_id, tries=1)
                if ident is not None:
                    found.append(Candidate(dxl_id, rate, ident.model, ident.firmware))
        if found:
            break
    set_rate(robot_baud)
    return found


def choose(candidates: list[Candidate], target: int, min_firmware: int) -> Candidate:
    if not candidates:
        raise ReplaceRefused(
            "no new servo answers at any standard baud rate; connect the new MX-28 (alone on "
            "its cable, or in its place in the chain) and switch the robot on"
        )
    if len(candidates) > 1:
        listed = ", ".join(f"ID {c.id} at {c.baud} bps" for c in candidates)
        raise ReplaceRefused(
            f"more than one candidate answers ({listed}); connect only the new servo"
        )
    c = candidates[0]
    if c.model != MX28_MODEL:
        raise ReplaceRefused(
            f"the candidate (ID {c.id} at {c.baud} bps) is a {MODELS.get(c.model, hex(c.model))},"
            " not an MX-28"
        )
    if c.firmware < min_firmware:
        raise ReplaceRefused(
            f"the new servo's firmware is {c.firmware} < {min_firmware} (1024 positions); update "
            "it with ROBOTIS's R+ Manager / Dynamixel Wizard first"
        )
    return c


def answers(bus: DxlBus, dxl_id: int, tries: int = 3) -> bool:
    return any(bus.ping(dxl_id) for _ in range(tries))


def check_free(bus: DxlBus, target: int) -> None:
    """Refuse when ``target`` already answers at the robot's rate."""
    if answers(bus, target):
        raise ReplaceRefused(
            f"ID {target} already answers at the robot's baud rate: nothing to replace "
            "(`darwin doctor` names the servo that is missing)"
        )


def program(
    bus: DxlBus,
    set_rate: Callable[[int], None],
    c: Candidate,
    target: int,
    robot_baud: int,
    s: ServoSettings,
) -> dict[str, int]:
    """Write the candidate's EEPROM, then read it back at the robot's rate; returns what was
    read. Raises ``ReplaceRefused`` when the read-back differs."""
    set_rate(c.baud)
    delay = s.return_delay_us // 2
    limits = struct.pack("<HH", s.cw_angle_limit, s.ccw_angle_limit)
    bus.write(c.id, MX28.RETURN_DELAY_TIME.reg.address, bytes([delay]), tries=3)
    bus.write(c.id, MX28.CW_ANGLE_LIMIT.reg.address, limits, tries=3)
    if c.id != target:
        bus.write_unanswered(c.id, MX28.ID.reg.address, bytes([target]))
        if not answers(bus, target):
            raise ReplaceRefused(f"the new servo did not take ID {target}; run the command again")
    data = _switch_rate(bus, set_rate, target, c.baud, robot_baud)
    if data is None:
        raise ReplaceRefused(
            f"ID {target} does not answer at {robot_baud} bps after its baud rate was set; "
            "run `darwin scan` and the command again"
        )
    got = {
        "id": data[0],
        "baud": units.baud_register_to_bps(data[1]),
        "return_delay_us": data[2] * 2,
        "cw_angle_limit": data[3] | data[4] << 8,
        "ccw_angle_limit": data[5] | data[6] << 8,
    }
    wanted = {
        "id": target,
        "baud": units.baud_register_to_bps(baud_register(robot_baud)),
        "return_delay_us": delay * 2,
        "cw_angle_limit": s.cw_angle_limit,
        "ccw_angle_limit": s.ccw_angle_limit,
    }
    wrong = {k: (got[k], v) for k, v in wanted.items() if got[k] != v}
    if wrong:
        listed = ", ".join(f"{k} {g} (wanted {w})" for k, (g, w) in wrong.items())
        raise ReplaceRefused(f"servo {target} reads back {listed}; run the command again")
    return got


def _switch_rate(
    bus: DxlBus, set_rate: Callable[[int], None], target: int, old: int, new: int
) -> bytes | None:
    """Write the baud rate register at ``old``, then read the EEPROM block back at ``new``.

    The status of that write (or its time-out) is what makes sure the instruction left at the
    old rate before the port changes rate. A servo that is silent at the new rate but still
    answers at the old one never took the write (a garbled packet, or a host that changed rate
    too soon): it is written again, a bounded number of times."""
    start = MX28.ID.reg.address
    length = MX28.CCW_ANGLE_LIMIT.reg.end - start
    for _ in range(BAUD_WRITES):
        set_rate(old)
        with contextlib.suppress(BusError):
            bus.write(target, MX28.BAUD_RATE.reg.address, bytes([baud_register(new)]))
        set_rate(new)
        # A servo applies a new rate after its status reply, and a busy host may ask before
        # that: keep asking for a bounded while.
        deadline = time.monotonic() + READBACK_S
        while True:
            try:
                return bus.read(target, start, length, tries=3)[0]
            except BusError:
                if time.monotonic() >= deadline:
                    break
        set_rate(old)
        if not answers_within(bus, target, READBACK_S):
            break  # silent at both rates: lost, not a write to repeat
    set_rate(new)
    return None


def answers_within(bus: DxlBus, dxl_id: int, seconds: float) -> bool:
    """Ping until ``dxl_id`` answers or ``seconds`` pass: a busy host can miss a reply's wire
    time, and one missed ping must not pass for a lost servo."""
    deadline = time.monotonic() + seconds
    while not answers(bus, dxl_id):
        if time.monotonic() >= deadline:
            return False
    return True


def power_on(bus: DxlBus, pause: Callable[[float], None], seconds: float) -> None:
    try:
        bus.write(CM730_ID, CM730.DXL_POWER.reg.address, b"\x01", tries=3)
    except BusError:
        raise ReplaceRefused(
            "the CM-730 does not answer at the robot's baud rate; is the robot switched on? "
            "(`darwin doctor`)"
        ) from None
    pause(seconds)
