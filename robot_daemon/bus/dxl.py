"""Dynamixel Protocol 1.0 transactions over dynamixel-sdk: read, write, sync write, bulk read.

Instruction packets are built here (:mod:`robot_daemon.bus.packet`) and written to the
transport. The bulk read receives without the SDK (:mod:`robot_daemon.bus.bulk_receive`): every
packet that does arrive is kept, matched by ID, in whatever order the devices answer, so one
silent or corrupt device costs only its own data. Single-device reads and writes still receive
with the SDK's ``rxPacket``.

Every wait for a reply is bounded by what that reply needs (:class:`ReplyBudget`): the wire
time of the bytes still to cross (10 µs a byte at 1 Mbps), the device's return delay and a
small margin from the config (``bus.reply_margin_ms``). A reply that never comes costs about
its own wire time, not a fixed timeout, so a lossy bus does not cost the loop its period.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TypeVar

from dynamixel_sdk import COMM_RX_CORRUPT, COMM_SUCCESS, Protocol1PacketHandler

from robot_daemon.bus.bulk_receive import (
    BulkPlan,
    BulkResult,
    blame,
    next_lateness,
    receive,
    split_tail,
)
from robot_daemon.bus.packet import PACKET_OVERHEAD, instruction_packet
from robot_daemon.bus.tables import BROADCAST_ID, MX28, ErrorBit, Instruction
from robot_daemon.bus.transport import Transport
from schemas import units
from schemas.errors import BusError, NoReplyError, PacketError, PortError

T = TypeVar("T")


# Until the scan has read a device's return delay, assume the longest it can be set to.
UNKNOWN_RETURN_DELAY_MS = units.return_delay_s(MX28.RETURN_DELAY_TIME.reg.high) * 1000.0


@dataclass
class ReplyBudget:
    """How long a reply may take: its bytes on the wire, the device's return delay, a margin.

    ``margin_ms`` covers what the wire model does not: the USB adapter's latency timer (1 ms
    when set as the README says), the host's scheduling, a Python emulator's."""

    margin_ms: float = 1.0
    delays_ms: dict[int, float] = field(default_factory=dict)  # by ID, learnt from the scan
    version: int = 0  # bumped by every change of a delay (plans made from them are stale)

    def set_return_delay(self, dxl_id: int, raw: int) -> None:
        self.delays_ms[dxl_id] = units.return_delay_s(raw) * 1000.0
        self.version += 1

    def reply_ms(
        self, byte_ms: float, dxl_id: int, reply_bytes: int, margin_ms: float | None = None
    ) -> float:
        """The wait for one reply of ``reply_bytes`` from ``dxl_id``, counted from the moment
        the line is free for it (the instruction sent, or the reply before it received);
        ``margin_ms`` in place of the budget's own margin."""
        delay = self.delays_ms.get(dxl_id, UNKNOWN_RETURN_DELAY_MS)
        return byte_ms * reply_bytes + delay + (self.margin_ms if margin_ms is None else margin_ms)


def error_names(bits: int) -> list[str]:
    return [b.name.lower() for b in ErrorBit if bits & b]


class DxlBus:
    """Transactions on one open transport. Not thread-safe: one thread (the motion loop) owns
    it."""

    def __init__(self, port: Transport, budget: ReplyBudget | None = None) -> None:
        self.port = port
        self.ph = Protocol1PacketHandler()
        self.budget = budget if budget is not None else ReplyBudget()
        # When the last byte the host has handed over is out on the wire (the transport's clock,
        # ms): a write returns before its bytes have crossed, and a reply cannot start before.
        self._wire_free = 0.0
        self._plans: dict[tuple[object, ...], BulkPlan] = {}
        # How much later than their wire time a bulk read's replies are all in (ms): the USB
        # adapter's latency timer, the host's scheduling, an emulator's pace. Learnt, so that
        # the receive wakes once, when they are in, rather than early and then again.
        self.late_ms = 0.0

    @property
    def name(self) -> str:
        name: str = self.port.port_name
        return name

    def _check(self, result: int, what: str, dxl_id: int) -> None:
        if result == COMM_SUCCESS:
            return
        text = self.ph.getTxRxResult(result)
        if result == COMM_RX_CORRUPT:
            raise PacketError(f"{what} of device {dxl_id} on {self.name}: corrupt reply ({text})")
        raise NoReplyError(
            f"{what} of device {dxl_id} on {self.name}: no reply ({text}); check the CM-730 "
            "power and the ID (`darwin scan`)"
        )

    def _send(
        self, dxl_id: int, instruction: int, params: Iterable[int], packet: bytes | None = None
    ) -> float:
        """Send one instruction packet (``packet`` when it is already built); returns when its
        last byte will be on the wire, behind whatever was sent before it. Built here (one
        ``bytes``, one checksum ``sum``) rather than by the SDK's ``txPacket``, whose per-byte
        Python loop ran twice a tick."""
        if packet is None:
            try:
                packet = instruction_packet(dxl_id, instruction, params)
            except ValueError as exc:
                name = Instruction(instruction).name
                raise BusError(f"{name} to {dxl_id} on {self.name}: {exc}") from exc
        port = self.port
        start = max(port.getCurrentTime(), self._wire_free)
        port.clearPort()  # a late reply to an earlier transaction must not pass for this one's
        if port.writePort(packet) != len(packet):
            name = Instruction(instruction).name
            raise BusError(f"{name} to {dxl_id} on {self.name}: the port took only part of it")
        self._wire_free = start + port.tx_time_per_byte * len(packet)
        return self._wire_free

    def _transact(
        self,
        dxl_id: int,
        instruction: int,
        params: Iterable[int],
        length: int,
        what: str,
        margin_ms: float | None = None,
    ) -> tuple[bytes, int]:
        """One instruction and its status packet (``length`` data bytes): (data, error bits)."""
        sent = self._send(dxl_id, instruction, params)
        port = self.port
        wait = self.budget.reply_ms(
            port.tx_time_per_byte, dxl_id, length + PACKET_OVERHEAD, margin_ms
        )
        port.setPacketTimeoutMillis(sent - port.getCurrentTime() + wait)
        port.is_using = True
        # The SDK takes any packet from that ID; a late reply to an earlier transaction (a bulk
        # read that timed out) would pass for this one. Only a reply of the right length counts.
        while True:
            rx, result = self.ph.rxPacket(port)
            self._check(result, what, dxl_id)
            if rx[2] == dxl_id and rx[3] == length + 2:
                return bytes(rx[5 : 5 + length]), rx[4]
            port.is_using = True

    # -- single-device transactions -----------------------------------------------------------
    def ping(self, dxl_id: int) -> bool:
        try:
            self._transact(dxl_id, Instruction.PING, (), 0, "PING")
        except PortError:
            raise
        except BusError:
            return False
        return True

    def read(
        self,
        dxl_id: int,
        address: int,
        length: int,
        tries: int = 1,
        retry_margin_ms: float | None = None,
    ) -> tuple[bytes, int]:
        """Read ``length`` bytes; returns (data, error bits) or raises ``BusError``. A missing or
        corrupt reply is asked for again, ``tries`` times in all; a lost port is not. The retries
        wait with ``retry_margin_ms`` when given: a reply that missed the loop's tight margin
        (a busy host, an emulator's pace) gets the patience of bring-up the second time."""
        what = f"READ {address}+{length}"
        params = (address, length)
        return _retry(
            tries,
            lambda margin: self._transact(dxl_id, Instruction.READ, params, length, what, margin),
            retry_margin_ms,
        )

    def write(
        self,
        dxl_id: int,
        address: int,
        data: bytes,
        tries: int = 1,
        retry_margin_ms: float | None = None,
    ) -> int:
        """WRITE and wait for the status packet; returns its error bits. Retried like
        :meth:`read` (writing the same value again is harmless)."""
        what = f"WRITE {address}+{len(data)}"
        params = (address, *data)
        return _retry(
            tries,
            lambda margin: self._transact(dxl_id, Instruction.WRITE, params, 0, what, margin)[1],
            retry_margin_ms,
        )

    def write_unanswered(self, dxl_id: int, address: int, data: bytes) -> None:
        """WRITE without waiting for its status: an ID or baud rate write is answered from the
        new ID, or at the old rate, which the next transaction must not wait for."""
        self._send(dxl_id, Instruction.WRITE, (address, *data))
        self.port.is_using = False  # the SDK frees the port on a receive; none follows

    # -- group transactions -------------------------------------------------------------------
    def sync_write(self, start: int, length: int, rows: dict[int, bytes]) -> int:
        """SYNC_WRITE ``length`` bytes from ``start`` to each id in ``rows``; returns bytes sent."""
        if not rows:
            return 0
        param: list[int] = [start, length]
        for dxl_id, data in rows.items():
            if len(data) != length:
                raise ValueError(f"sync write row for {dxl_id} has {len(data)} bytes, not {length}")
            param.append(dxl_id)
            param.extend(data)
        self._send(BROADCAST_ID, Instruction.SYNC_WRITE, param)
        self.port.is_using = False
        return len(param) + PACKET_OVERHEAD

    def sync_write_rows(self, start: int, length: int, rows: bytes) -> int:
        """SYNC_WRITE with the rows (each: id, then ``length`` bytes) already packed."""
        if not rows:
            return 0
        if len(rows) % (length + 1):
            raise ValueError(f"sync write rows of {len(rows)} bytes are not rows of {length + 1}")
        self._send(BROADCAST_ID, Instruction.SYNC_WRITE, bytes((start, length)) + rows)
        self.port.is_using = False
        return len(rows) + 2 + PACKET_OVERHEAD

    def bulk_read(self, blocks: Iterable[tuple[int, int, int]]) -> BulkResult:
        """BULK_READ ``(id, start, length)`` blocks; every reply that arrives is kept."""
        blocks = list(blocks)
        out = BulkResult()
        if not blocks:
            return out
        missing, heard = self._bulk_once(blocks, out)
        if not missing:
            return out  # everyone answered: nothing to blame, nothing to ask again
        if not heard:
            # Not one byte came back: the bus (or the adapter) stalled, not a device. Every
            # reading is stale this tick; nobody is blamed.
            out.stalled = True
            out.missing = missing
            return out
        # On the real bus a device waits for the one before it, so a silent device silences the
        # rest: when several in a row at the end were not heard, ask again for them, the first
        # silent one last so that, if it is still silent, it delays nobody. A device heard after
        # a missing one shows the chain held: that one is simply missing.
        scattered, tail = split_tail(blocks, missing, heard)
        if len(tail) > 1:
            out.retried = True
            again = [b for b in blocks if b[0] in tail[1:]]
            again += [b for b in blocks if b[0] == tail[0]]
            missing_again, heard_again = self._bulk_once(again, out)
            out.missing = scattered + missing_again
            if heard_again:
                out.blamed = scattered + blame(again, missing_again, heard_again)
            else:
                out.blamed = [*scattered, tail[0]]
        else:
            out.missing = missing
            out.blamed = scattered + tail
        return out

    def _plan(self, blocks: list[tuple[int, int, int]]) -> BulkPlan:
        """What a bulk read of ``blocks`` needs beside its replies, made once per block list
        (the loop cycles through a few dozen) rather than every tick."""
        budget = self.budget
        key = (tuple(blocks), budget.margin_ms, budget.version, self.port.tx_time_per_byte)
        plan = self._plans.get(key)
        if plan is None:
            if len(self._plans) > 256:
                self._plans.clear()
            plan = self._plans[key] = BulkPlan.make(blocks, budget, self.port.tx_time_per_byte)
        return plan

    def _bulk_once(
        self, blocks: list[tuple[int, int, int]], out: BulkResult
    ) -> tuple[list[int], set[int]]:
        """One BULK_READ; returns the IDs whose data did not come, and the IDs heard at all
        (a garbled reply was still on the wire)."""
        plan = self._plan(blocks)
        sent = self._send(BROADCAST_ID, Instruction.BULK_READ, (), plan.packet)
        got = receive(self.port, plan, sent, self.late_ms, out)
        if got.seen_ms is not None:
            self.late_ms = next_lateness(self.late_ms, got.woken, got.seen_ms)
        return got.missing, got.heard


def _retry(
    tries: int, once: Callable[[float | None], T], retry_margin_ms: float | None = None
) -> T:
    for attempt in range(max(1, tries)):
        try:
            return once(None if attempt == 0 else retry_margin_ms)
        except PortError:
            raise
        except BusError:
            if attempt >= tries - 1:
                raise
    raise AssertionError("unreachable")
