"""Dynamixel Protocol 1.0 transactions over dynamixel-sdk: read, write, sync write, bulk read.

Instruction packets are built here (:mod:`robot_daemon.bus.packet`) and written to the
transport. The bulk read receives without the SDK: it reads whatever has arrived in one call
(:meth:`Transport.read_chunk`) and frames every status packet in it in one pass
(:class:`PacketParser`), so one silent or corrupt device costs only its own data: every packet
that does arrive is kept, matched by ID, in whatever order the devices answer. Single-device
reads and writes still receive with the SDK's ``rxPacket``.

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

from robot_daemon.bus.packet import PACKET_OVERHEAD, Packet, PacketParser, instruction_packet
from robot_daemon.bus.tables import BROADCAST_ID, MX28, ErrorBit, Instruction
from robot_daemon.bus.transport import Transport
from schemas import units
from schemas.errors import BusError, NoReplyError, PacketError, PortError

T = TypeVar("T")

# The learnt lateness of a bulk read's replies (DxlBus.late_ms): how fast it comes down after a
# read that was all in at once, and its ceiling (ms).
LATENESS_STEP_MS = 0.02
MAX_LATENESS_MS = 2.0

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

    def reply_ms(self, byte_ms: float, dxl_id: int, reply_bytes: int) -> float:
        """The wait for one reply of ``reply_bytes`` from ``dxl_id``, counted from the moment
        the line is free for it (the instruction sent, or the reply before it received)."""
        delay = self.delays_ms.get(dxl_id, UNKNOWN_RETURN_DELAY_MS)
        return byte_ms * reply_bytes + delay + self.margin_ms


def error_names(bits: int) -> list[str]:
    return [b.name.lower() for b in ErrorBit if bits & b]


@dataclass
class BulkResult:
    """Data of one bulk read: id → bytes for every device that answered correctly."""

    data: dict[int, bytes] = field(default_factory=dict)
    errors: dict[int, int] = field(default_factory=dict)  # id → error bits of its status packet
    missing: list[int] = field(default_factory=list)  # no data this time
    # The missing ones whose silence is their own: a device heard after them shows the chain
    # held, or they were the first of the devices not heard at the end (on the real bus, the
    # one that silences the rest). The others at the end were cut off with it, or by a late bus.
    blamed: list[int] = field(default_factory=list)
    corrupt: int = 0  # packets dropped for a bad checksum or length
    retried: bool = False
    stalled: bool = False  # nothing answered at all


@dataclass(frozen=True)
class _BulkPlan:
    param: list[int]  # the BULK_READ parameters
    want: dict[int, int]  # id → data length
    order: list[int]  # ids in the order asked
    rank: dict[int, int]  # id → its place in ``order``
    waits: list[float]  # ms, each reply's own wait (wire time, return delay, margin)
    all_waits: float  # ms, their sum: the longest the transaction may take after the request
    wire: float  # ms, when every reply is in if all goes well (no margins)
    packet: bytes  # the BULK_READ instruction packet itself
    # (id, data length, the packet's LEN byte) in order: what an in-order answer looks like
    expect: list[tuple[int, int, int]]
    tail: list[int]  # bytes of the replies from each one in order to the end

    @classmethod
    def make(
        cls, blocks: list[tuple[int, int, int]], budget: ReplyBudget, byte_ms: float
    ) -> _BulkPlan:
        param: list[int] = [0x00]  # the protocol's leading 0
        for dxl_id, start, length in blocks:
            param += [length, dxl_id, start]
        want = {dxl_id: length for dxl_id, _, length in blocks}
        order = [dxl_id for dxl_id, _, _ in blocks]
        waits = [budget.reply_ms(byte_ms, i, want[i] + PACKET_OVERHEAD) for i in order]
        wire = sum(
            byte_ms * (want[i] + PACKET_OVERHEAD) + budget.delays_ms.get(i, 0.0) for i in order
        )
        rank = {dxl_id: k for k, dxl_id in enumerate(order)}
        packet = instruction_packet(BROADCAST_ID, Instruction.BULK_READ, param)
        expect = [(i, want[i], want[i] + 2) for i in order]
        sizes = [want[i] + PACKET_OVERHEAD for i in order]
        tail = [sum(sizes[k:]) for k in range(len(sizes))]
        return cls(param, want, order, rank, waits, sum(waits), wire, packet, expect, tail)


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
        self._plans: dict[tuple[object, ...], _BulkPlan] = {}
        # How much later than their wire time a bulk read's replies are all in (ms): the USB
        # adapter's latency timer, the host's scheduling, an emulator's pace. Learnt, so that
        # the receive wakes once, when they are in, rather than early and then again.
        self.late_ms = 0.0

    @property
    def name(self) -> str:
        return self.port.port_name

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
        self, dxl_id: int, instruction: int, params: Iterable[int], length: int, what: str
    ) -> tuple[bytes, int]:
        """One instruction and its status packet (``length`` data bytes): (data, error bits)."""
        sent = self._send(dxl_id, instruction, params)
        port = self.port
        wait = self.budget.reply_ms(port.tx_time_per_byte, dxl_id, length + PACKET_OVERHEAD)
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

    def read(self, dxl_id: int, address: int, length: int, tries: int = 1) -> tuple[bytes, int]:
        """Read ``length`` bytes; returns (data, error bits) or raises ``BusError``. A missing or
        corrupt reply is asked for again, ``tries`` times in all; a lost port is not."""
        what = f"READ {address}+{length}"
        return _retry(
            tries, lambda: self._transact(dxl_id, Instruction.READ, (address, length), length, what)
        )

    def write(self, dxl_id: int, address: int, data: bytes, tries: int = 1) -> int:
        """WRITE and wait for the status packet; returns its error bits. Retried like
        :meth:`read` (writing the same value again is harmless)."""
        what = f"WRITE {address}+{len(data)}"
        params = (address, *data)
        return _retry(
            tries, lambda: self._transact(dxl_id, Instruction.WRITE, params, 0, what)[1]
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
        scattered, tail = _split_tail(blocks, missing, heard)
        if len(tail) > 1:
            out.retried = True
            again = [b for b in blocks if b[0] in tail[1:]]
            again += [b for b in blocks if b[0] == tail[0]]
            missing_again, heard_again = self._bulk_once(again, out)
            out.missing = scattered + missing_again
            if heard_again:
                out.blamed = scattered + _blame(again, missing_again, heard_again)
            else:
                out.blamed = [*scattered, tail[0]]
        else:
            out.missing = missing
            out.blamed = scattered + tail
        return out

    def _learn_lateness(self, woken: int, seen_ms: float) -> None:
        self.late_ms = _next_lateness(self.late_ms, woken, seen_ms)

    def _plan(self, blocks: list[tuple[int, int, int]]) -> _BulkPlan:
        """What a bulk read of ``blocks`` needs beside its replies, made once per block list
        (the loop cycles through a few dozen) rather than every tick."""
        budget = self.budget
        key = (tuple(blocks), budget.margin_ms, budget.version, self.port.tx_time_per_byte)
        plan = self._plans.get(key)
        if plan is None:
            if len(self._plans) > 256:
                self._plans.clear()
            plan = self._plans[key] = _BulkPlan.make(blocks, budget, self.port.tx_time_per_byte)
        return plan

    def _bulk_once(
        self, blocks: list[tuple[int, int, int]], out: BulkResult
    ) -> tuple[list[int], set[int]]:
        """One BULK_READ; returns the IDs whose data did not come, and the IDs heard at all
        (a garbled reply was still on the wire)."""
        plan = self._plan(blocks)
        sent = self._send(BROADCAST_ID, Instruction.BULK_READ, (), plan.packet)
        port = self.port
        want, order, rank, waits = plan.want, plan.order, plan.rank, plan.waits
        # Replies come in bus order, so each wait is for the next device due after the last one
        # heard: the first one after the instruction has crossed the wire, each later one after
        # the reply before it. Once a device is heard, the ones before it that were not never
        # will be: nobody waits for them. The whole transaction never takes longer than every
        # reply's own wait, however the replies trickle in.
        final = sent + plan.all_waits
        # When every reply should be in if all goes well (no margins): reads wait for that,
        # never past a deadline, so the loop wakes a few times per bulk read, not per reply.
        whole = sent + plan.wire + self.late_ms
        woken = 0  # reads so far: the first that finds everything in means we slept enough
        due = 0  # index in ``order`` of the next device waited for; len(order): none
        deadline = sent + waits[0]
        pending = set(order)
        heard: set[int] = set()
        data, errors = out.data, out.errors
        # Whatever has arrived is read in one call and every complete packet in it framed in
        # one pass: on an FTDI that is one wake-up per 62-byte USB packet, not one SDK round
        # trip (header, then body, each a read) per device.
        parser = PacketParser()
        # The usual case costs one comparison per reply: replies in the order asked, each
        # whole, are taken straight off the bytes (``raw`` from ``pos``); the first thing that
        # is not that hands the rest to the parser, which copes with anything.
        raw = bytearray()
        pos = 0
        expect = plan.expect
        n = len(order)
        in_order = True
        while due < n:
            limit = min(deadline, final)
            port.idle_until(min(whole, limit))
            chunk = port.read_chunk(limit)
            woken += 1
            if not chunk:
                break  # the reply due is not coming
            if in_order:
                raw += chunk
                have = len(raw)
                while due < n:
                    dxl_id, length, code = expect[due]
                    end = pos + length + PACKET_OVERHEAD
                    if have < end:
                        break
                    if (
                        raw[pos] != 0xFF
                        or raw[pos + 1] != 0xFF
                        or raw[pos + 2] != dxl_id
                        or raw[pos + 3] != code
                        or (~sum(raw[pos + 2 : end - 1]) & 0xFF) != raw[end - 1]
                    ):
                        in_order = False
                        break
                    data[dxl_id] = bytes(raw[pos + 5 : end - 1])
                    if raw[pos + 4]:
                        errors[dxl_id] = raw[pos + 4]
                    pending.discard(dxl_id)
                    heard.add(dxl_id)
                    due += 1
                    pos = end
                if in_order:
                    if due < n:
                        now = port.getCurrentTime()
                        deadline = now + waits[due]
                        # The rest cannot be in before its bytes have crossed: sleep until then
                        # rather than wake for every reply that trickles in.
                        rest = plan.tail[due] - (have - pos)
                        whole = max(whole, now + rest * port.tx_time_per_byte)
                    continue
                chunk = bytes(raw[pos:])
            for frame in parser.feed(chunk):
                dxl_id = frame.id
                k = rank.get(dxl_id)
                if (
                    k is not None
                    and dxl_id in pending
                    and type(frame) is Packet
                    and len(frame.params) == want[dxl_id]
                ):
                    data[dxl_id] = frame.params
                    if frame.code:
                        errors[dxl_id] = frame.code
                    pending.discard(dxl_id)
                elif dxl_id not in data:  # (a second copy is a late echo, not a fault)
                    out.corrupt += 1
                if k is not None:
                    heard.add(dxl_id)
                    due = max(due, k + 1)  # one answering out of turn does not rewind the wait
                    while due < n and order[due] not in pending:
                        due += 1
            if due < n:
                deadline = port.getCurrentTime() + waits[due]
        if in_order and due == n:
            self._learn_lateness(woken, port.getCurrentTime() - (sent + plan.wire))
        if in_order and len(raw) - pos >= 3 and raw[pos] == 0xFF and raw[pos + 1] == 0xFF:
            parser.feed(bytes(raw[pos : pos + 3]))  # a reply cut short: who was talking
        late = parser.pending_id
        if late is not None and late in want:
            heard.add(late)  # cut short on the wire: the device was still talking
        return [i for i in order if i in pending], heard


def _next_lateness(late_ms: float, woken: int, seen_ms: float) -> float:
    """The lateness to sleep for next time: a little less after a bulk read that was all in at
    the first read (it may have been in earlier), part of the way to what was seen after one
    that needed more reads. Bounded, so a stall does not make the loop sleep through its tick."""
    if woken <= 1:
        return max(0.0, late_ms - LATENESS_STEP_MS)
    return min(MAX_LATENESS_MS, late_ms + (max(seen_ms, late_ms) - late_ms) * 0.5)


def _split_tail(
    blocks: list[tuple[int, int, int]], missing: list[int], heard: set[int]
) -> tuple[list[int], list[int]]:
    """The missing IDs before the last device heard, and those after it (in bus order)."""
    order = [b[0] for b in blocks]
    last = max((k for k, i in enumerate(order) if i in heard), default=-1)
    before = [i for i in missing if order.index(i) < last]
    return before, [i for i in missing if order.index(i) > last]


def _blame(blocks: list[tuple[int, int, int]], missing: list[int], heard: set[int]) -> list[int]:
    before, tail = _split_tail(blocks, missing, heard)
    return before + tail[:1]


def _retry(tries: int, once: Callable[[], T]) -> T:
    for attempt in range(max(1, tries)):
        try:
            return once()
        except PortError:
            raise
        except BusError:
            if attempt >= tries - 1:
                raise
    raise AssertionError("unreachable")
