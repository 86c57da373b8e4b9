"""The simulated Dynamixel bus: a CM-730 and MX-28 servos answering Protocol 1.0 frames.

:meth:`Bus.handle` takes one parsed frame and returns the status packets the devices send, in
bus order. No I/O and no clock of its own: the emulator feeds it bytes from the pty and time
through :meth:`Bus.step`, and applies wire timing and faults to what it returns.

Which instructions answer (as the firmware does):

* status return level 0: PING only; 1: PING, READ and BULK_READ; 2: everything;
* broadcast (ID 254): SYNC_WRITE, WRITE, REG_WRITE, ACTION and RESET act silently; BULK_READ is
  answered by each listed device in the listed order, as a daisy chain: each device sends its
  status packet after it has heard the one listed before it, so a device that does not answer
  (absent, silent, status return level 0, its reply dropped) silences every one after it for
  that bulk read (the MX-28 e-manual, "Bulk Read": "the Dynamixel with ID … waits for the
  previous Dynamixel's status packet"); PING and READ to 254 get no answer;
* ``cm730_late_reads``: the CM-730 ignores that many READ and BULK_READ instructions first (a
  CM-730 still booting, or a host whose reads it misses), then answers;
* a frame with a bad checksum is not executed; the addressed device answers with CHECKSUM
  (0x10) if its return level would answer that instruction;
* an unknown instruction, wrong parameter count, ACTION with nothing registered or SYNC_WRITE
  and BULK_READ to a single ID earn INSTRUCTION (0x40);
* servos behind the CM-730 are silent and inert while DXL_POWER is 0 and for
  ``power_on_delay_s`` after it becomes 1; a ``silent`` ID never answers but still obeys;
* only devices at the line's baud rate hear a frame, and servos behind a broken cable hear
  nothing (:mod:`robot_daemon.emulator.wiring`);
* two devices with one ID (a replaced or firmware-recovered servo given an ID in use) both obey
  every instruction to it and both answer: their status packets collide on the line
  ("identical ID … will cause communication collision among multiple DYNAMIXEL modules",
  ROBOTIS, forum.robotis.com/t/robotis-op2-dxl-communication-error/1700), modelled as a wired
  AND (a 0 bit wins on the idle-high line), so identical packets (a ping's, an identity read's)
  pass unharmed and differing ones (present positions) arrive garbled; in a bulk read the
  devices after it never hear the status packet they wait for.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

from robot_daemon.bus.chains import hidden_behind
from robot_daemon.bus.packet import BadChecksum, Frame, Packet, status_packet
from robot_daemon.bus.tables import (
    BROADCAST_ID,
    CM730,
    CM730_ID,
    MX28,
    SERVO_IDS,
    ErrorBit,
    Instruction,
)
from robot_daemon.emulator.devices import CM730Device, Device, Environment, Servo
from robot_daemon.emulator.wiring import hears, make_factory_fresh
from schemas import units

_MAX_READ = 250 - 6  # a status packet must fit the SDK's 250-byte receive buffer
_READ_ONLY = frozenset((Instruction.PING, Instruction.READ, Instruction.BULK_READ))
_READS = frozenset((Instruction.READ, Instruction.BULK_READ))
_PLAIN_WRITES = frozenset((Instruction.WRITE, Instruction.SYNC_WRITE))
# Who answers an ID hangs on these registers (at the same addresses on the MX-28 and CM-730).
_INDEX_END = max(r.value.end for r in (MX28.ID, MX28.BAUD_RATE, CM730.ID, CM730.BAUD_RATE))
# Bounds of what bulk reads keep (a host asking ever new layouts empties them and goes on).
_KEPT_PLANS = 64
_KEPT_REPLIES = 256


class Reply(NamedTuple):
    """A status packet a device sends. A tuple: 21 of them a bulk read, 125 bulk reads a
    second, and a frozen dataclass costs a Python ``__setattr__`` call a field to make."""

    device_id: int
    packet: bytes
    return_delay_s: float


def _answers(level: int, instruction: int) -> bool:
    if instruction == Instruction.PING:
        return True
    if level == 1:
        return instruction in (Instruction.READ, Instruction.BULK_READ)
    return level >= 2


class Bus:
    def __init__(
        self,
        rng: np.random.Generator,
        env: Environment | None = None,
        servo_ids: Iterable[int] = SERVO_IDS,
        imu_noise: float = 1.0,
        gyro_full_scale_dps: float = units.GYRO_DPS_FULL_SCALE,
        power_on_delay_s: float = 0.3,
        initial_positions: dict[int, int] | None = None,
    ) -> None:
        self.env = env or Environment()
        self.cm730 = CM730Device(self.env, rng, imu_noise, gyro_full_scale_dps)
        self.cm730.on_power = self._on_power
        positions = initial_positions or {}
        centre = units.POSITION_CENTER
        self.servos = {i: Servo(i, self.env, positions.get(i, centre)) for i in servo_ids}
        self.power_on_delay_s = power_on_delay_s
        self.silent: set[int] = set()
        self.line_bps = 1_000_000  # the rate the host's port runs at (set by the emulator)
        self.broken_after: list[int] = []  # cable breaks, each right after this servo
        self.cut_off: set[int] = set()  # the servos (configured IDs) those breaks hide
        self.fresh: set[int] = set()  # servos (configured IDs) swapped for factory-fresh ones
        self.cm730_late_reads = 0  # READ/BULK_READ instructions the CM-730 ignores first
        self.time = 0.0
        self._power_ready_at: float | None = None
        self._registered: dict[int, tuple[int, bytes]] = {}
        # ID → the devices answering it (more than one: a shared ID), rebuilt after anything
        # that can change who answers (power, writes).
        self._index: dict[int, list[Device]] | None = None
        # Bulk reads' (length, ID, address) blocks by their parameters: the daemon asks a
        # handful of layouts (the slow block goes round the servos), 125 times a second.
        self._bulk_plans: dict[bytes, list[tuple[int, int, int]]] = {}
        # And each one's devices, while the index they were found in is the bus's.
        self._lone_plans: dict[
            bytes,
            tuple[dict[int, list[Device]], list[tuple[Device, tuple[int, int, int]]] | None],
        ] = {}
        # A device's last reply to a block of a bulk read, when reading it changed nothing,
        # with what the read depends on (Device.read_key): a robot standing still is asked
        # the same and answers the same bytes. False: always build them.
        self.reuse_replies = True
        self._replies: dict[tuple[int, int, int], tuple[tuple[object, ...], list[Reply]]] = {}

    # ---- power and time -----------------------------------------------------------------------

    @property
    def servo_power(self) -> bool:
        return any(s.powered for s in self.servos.values())

    def _on_power(self, on: bool) -> None:
        self._index = None
        if not on:
            self._power_ready_at = None
            for servo in self.servos.values():
                servo.power(False)
        elif self._power_ready_at is None and not self.servo_power:
            self._power_ready_at = self.time + self.power_on_delay_s
            self._check_power()

    def _check_power(self) -> None:
        if self._power_ready_at is not None and self.time >= self._power_ready_at - 1e-9:
            self._power_ready_at = None
            self._index = None
            for servo in self.servos.values():
                servo.power(True)

    def step(self, dt: float) -> None:
        self.time += dt
        self._check_power()
        for servo in self.servos.values():
            servo.step(dt)

    def restore(self, power: bool | None = None) -> None:
        """Every device back to its defaults and its configured ID, the servo bus powered as
        ``power`` says or, if None, as it was (tests and the ``restore`` control op: undo
        whatever a client wrote)."""
        powered = self.servo_power if power is None else power
        self._registered.clear()
        self.cm730.factory_reset()
        self.cm730.table[CM730.ID] = CM730_ID
        for dxl_id, servo in self.servos.items():
            servo.factory_reset()
            servo.table[MX28.ID] = dxl_id
            servo.power(False)
            if dxl_id in self.fresh:
                make_factory_fresh(servo)
        if powered:
            self.cm730.table[CM730.DXL_POWER] = 1
            for servo in self.servos.values():
                servo.power(True)
        self._index = None

    # ---- addressing -----------------------------------------------------------------------------

    def devices(self) -> list[Device]:
        """Every device that hears the bus right now (CM-730 first)."""
        servos = (s for i, s in self.servos.items() if s.powered and i not in self.cut_off)
        return [d for d in (self.cm730, *servos) if hears(d, self.line_bps)]

    def set_line_bps(self, bps: int) -> None:
        if bps != self.line_bps:
            self.line_bps = bps
            self._index = None

    def break_chain(self, after: list[int]) -> None:
        """Cable breaks right after each servo of ``after`` ([] mends them all)."""
        cut = hidden_behind(after)  # refuses an ID on no chain before anything changes
        self.broken_after, self.cut_off = sorted(set(after)), cut
        self._index = None

    def factory_fresh(self, dxl_id: int, fresh_id: int = 1) -> None:
        """Swap servo ``dxl_id`` for a factory-fresh MX-28 (ID 1, 57,600 bps; tests may give it
        another ``fresh_id``): what a servo replacement starts from. ``restore`` keeps it fresh."""
        make_factory_fresh(self.servo(dxl_id))
        self.servo(dxl_id).table[MX28.ID] = fresh_id
        self.fresh.add(dxl_id)
        self._index = None

    def device(self, dxl_id: int) -> Device | None:
        """The device answering ``dxl_id`` (the first, on a shared ID)."""
        devs = self.sharing(dxl_id)
        return devs[0] if devs else None

    def sharing(self, dxl_id: int) -> list[Device]:
        """Every device answering ``dxl_id``, in bus order (two or more: a shared ID)."""
        return self._by_id().get(dxl_id, [])

    def _by_id(self) -> dict[int, list[Device]]:
        if self._index is None:
            self._index = {}
            for dev in self.devices():
                self._index.setdefault(dev.id, []).append(dev)
        return self._index

    def set_id(self, dxl_id: int, new_id: int) -> None:
        """Give servo ``dxl_id`` (configured ID) the ID ``new_id``, as a servo replaced with a
        wrong ID is: ``new_id`` in use makes two servos answer it."""
        if not 0 <= new_id < BROADCAST_ID:
            raise ValueError(f"ID {new_id} is outside 0..253")
        self.servo(dxl_id).table[MX28.ID] = new_id
        self._index = None

    def servo(self, dxl_id: int) -> Servo:
        """A servo by its configured ID, powered or not (for the control API)."""
        try:
            return self.servos[dxl_id]
        except KeyError:
            raise KeyError(
                f"no servo with ID {dxl_id} on the simulated bus "
                f"(IDs {min(self.servos)}..{max(self.servos)})"
            ) from None

    def _reply(
        self, dev: Device, instruction: int, error: int, data: bytes = b"", level: int | None = None
    ) -> list[Reply]:
        dxl_id = dev.id
        level = dev.status_return_level if level is None else level
        if dxl_id in self.silent or (level < 2 and not _answers(level, instruction)):
            return []
        if dev is self.cm730 and self.cm730_late_reads > 0 and instruction in _READS:
            self.cm730_late_reads -= 1
            return []
        return [Reply(dxl_id, status_packet(dxl_id, error, data), dev.return_delay_s)]

    # ---- frames ------------------------------------------------------------------------------

    def handle(self, frame: Frame) -> list[Reply]:
        try:
            return self._handle(frame)
        finally:
            if frame.code not in _READ_ONLY and not _spares_index(frame):
                self._index = None  # a write may have changed an ID or a baud rate

    def _handle(self, frame: Frame) -> list[Reply]:
        if isinstance(frame, BadChecksum):
            return _collide(
                [
                    r
                    for dev in self.sharing(frame.id)
                    for r in self._reply(dev, frame.code, ErrorBit.CHECKSUM | dev.alarm_bits())
                ]
            )
        if frame.id == BROADCAST_ID:
            return self._broadcast(frame)
        replies: list[Reply] = []
        for dev in self.sharing(frame.id):  # a shared ID: every one obeys, and answers
            level = dev.status_return_level  # the level the packet arrived under decides
            error, data = self._execute(dev, frame)
            replies += self._reply(dev, frame.code, error, data, level)
        return _collide(replies)

    def _execute(self, dev: Device, p: Packet) -> tuple[int, bytes]:
        inst, params = p.code, p.params
        if inst == Instruction.PING:
            return dev.alarm_bits(), b""
        if inst == Instruction.READ:
            if len(params) != 2:
                return ErrorBit.INSTRUCTION | dev.alarm_bits(), b""
            address, length = params
            if length > _MAX_READ:
                return ErrorBit.RANGE | dev.alarm_bits(), b""
            data, error = dev.read(address, length)
            return error, data
        if inst == Instruction.WRITE:
            if len(params) < 2:
                return ErrorBit.INSTRUCTION | dev.alarm_bits(), b""
            return dev.write(params[0], params[1:]), b""
        if inst == Instruction.REG_WRITE:
            if len(params) < 2:
                return ErrorBit.INSTRUCTION | dev.alarm_bits(), b""
            self._register(dev, params[0], params[1:])
            return dev.alarm_bits(), b""
        if inst == Instruction.ACTION:
            return self._action(dev) | dev.alarm_bits(), b""
        if inst == Instruction.RESET:
            self._reset(dev)
            return dev.alarm_bits(), b""
        return ErrorBit.INSTRUCTION | dev.alarm_bits(), b""

    def _register(self, dev: Device, address: int, data: bytes) -> None:
        self._registered[id(dev)] = (address, bytes(data))
        if MX28.REGISTERED in dev.table.registers:
            dev.table[MX28.REGISTERED] = 1

    def _action(self, dev: Device) -> int:
        pending = self._registered.pop(id(dev), None)
        if pending is None:
            return ErrorBit.INSTRUCTION
        if MX28.REGISTERED in dev.table.registers:
            dev.table[MX28.REGISTERED] = 0
        return dev.write(*pending)

    def _reset(self, dev: Device) -> None:
        self._registered.pop(id(dev), None)
        dev.factory_reset()
        if dev is self.cm730:
            self._on_power(False)

    def _broadcast(self, p: Packet) -> list[Reply]:
        inst, params = p.code, p.params
        if inst == Instruction.SYNC_WRITE:
            self._sync_write(params)
        elif inst == Instruction.BULK_READ:
            return self._bulk_read(params)
        elif inst in (Instruction.WRITE, Instruction.REG_WRITE) and len(params) >= 2:
            for dev in self.devices():
                if inst == Instruction.WRITE:
                    dev.write(params[0], params[1:])
                else:
                    self._register(dev, params[0], params[1:])
        elif inst == Instruction.ACTION:
            for dev in self.devices():
                if id(dev) in self._registered:
                    self._action(dev)
        elif inst == Instruction.RESET:
            for dev in self.devices():
                self._reset(dev)
        return []

    def _sync_write(self, params: bytes) -> None:
        if len(params) < 2 or params[1] == 0:
            return
        start, size = params[0], params[1]
        block = size + 1
        body = params[2:]
        # An incomplete trailing block is ignored; complete blocks before it still apply.
        for i in range(0, len(body) - block + 1, block):
            for dev in self.sharing(body[i]):
                dev.write(start, body[i + 1 : i + block])

    def _bulk_read(self, params: bytes) -> list[Reply]:
        by_id = self._by_id()
        blocks = self._bulk_plans.get(params)
        if blocks is None:
            body = params[1:]  # params[0] is the 0x00 the protocol puts first
            blocks = [(body[i], body[i + 1], body[i + 2]) for i in range(0, len(body) - 2, 3)]
            if len(self._bulk_plans) >= _KEPT_PLANS:  # a host asking ever new ones
                self._bulk_plans.clear()
                self._lone_plans.clear()
            self._bulk_plans[params] = blocks
        lone = self._lone_plans.get(params)
        if lone is None or lone[0] is not by_id:  # (the index is a new dict when it changes)
            lone = self._lone_plans[params] = (by_id, _lone(blocks, by_id))
        if lone[1] is not None:
            return self._bulk_read_lone(lone[1])
        replies: list[Reply] = []
        for length, dxl_id, address in blocks:
            devs = by_id.get(dxl_id)
            if not devs:
                break  # nobody sends this status packet: the next device waits for ever
            if len(devs) == 1 and length <= _MAX_READ:
                reply = self._bulk_reply(devs[0], (id(devs[0]), address, length))
            else:
                reply = []
                for dev in devs:
                    if length > _MAX_READ:
                        reply += self._reply(dev, Instruction.BULK_READ, ErrorBit.RANGE)
                    else:
                        data, error = dev.read(address, length)
                        reply += self._reply(dev, Instruction.BULK_READ, error, data)
            if not reply:
                break  # silent: the chain stops here
            if len(reply) == 1:  # one device with this ID: nothing to collide with
                replies += reply
                continue
            collided = _collide(reply)
            replies += collided
            if collided[0].packet not in (r.packet for r in reply):
                break  # garbled: the next device never hears the packet it waits for
        return replies

    def _bulk_read_lone(self, plan: list[tuple[Device, tuple[int, int, int]]]) -> list[Reply]:
        """The loop above for a bulk read whose every block has one device and a length that
        fits (nearly all of them), through its devices found once."""
        replies: list[Reply] = []
        for dev, block in plan:
            reply = self._bulk_reply(dev, block)
            if not reply:
                break
            replies += reply
        return replies

    def _bulk_reply(self, dev: Device, block: tuple[int, int, int]) -> list[Reply]:
        """One device's answer to its ``block`` of a bulk read (``(id(dev), address,
        length)``): the one it gave last time when nothing it depends on has changed since (its
        read key, and not silenced)."""
        key = dev.read_key() if self.reuse_replies else None
        if key is not None and not (self.silent and dev.id in self.silent):
            last = self._replies.get(block)
            if last is not None and last[0] == key:
                return last[1]
        _, address, length = block
        data, error = dev.read(address, length)
        reply = self._reply(dev, Instruction.BULK_READ, error, data)
        # Kept only when the read changed nothing (an alarm it latched changes the key), and
        # only an answer: a silenced device's none would outlast the silence (not in the key).
        if key is not None and reply and dev.read_key() == key:
            if len(self._replies) >= _KEPT_REPLIES:
                self._replies.clear()
            self._replies[block] = (key, reply)
        return reply


def _lone(
    blocks: list[tuple[int, int, int]], by_id: dict[int, list[Device]]
) -> list[tuple[Device, tuple[int, int, int]]] | None:
    """Each block's one device and its reply's key in ``Bus._replies``; None if a block has
    none, or more than one, or asks more than a status packet holds."""
    plan = []
    for length, dxl_id, address in blocks:
        devs = by_id.get(dxl_id)
        if devs is None or len(devs) != 1 or length > _MAX_READ:
            return None
        plan.append((devs[0], (id(devs[0]), address, length)))
    return plan


def _spares_index(frame: Frame) -> bool:
    """A WRITE or SYNC_WRITE that starts after the ID and baud rate registers (every goal the
    host sends) leaves who answers each ID as it was: the index outlives it. (Power, cable
    breaks and the line's rate reset the index where they change.)"""
    return (
        type(frame) is Packet
        and frame.code in _PLAIN_WRITES
        and bool(frame.params)
        and frame.params[0] >= _INDEX_END
    )


def _collide(replies: list[Reply]) -> list[Reply]:
    """What the host receives when these devices answer at once: one packet, their bytes ANDed
    (a 0 bit wins on the idle-high line); identical packets pass unharmed."""
    if len(replies) < 2:
        return replies
    out = bytearray(b"\xff" * max(len(r.packet) for r in replies))
    for r in replies:
        for i, b in enumerate(r.packet):
            out[i] &= b
    return [Reply(replies[0].device_id, bytes(out), min(r.return_delay_s for r in replies))]
