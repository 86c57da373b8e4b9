"""The bulk read's receive path: the plan of one transaction, and its replies read off the
transport.

Whatever has arrived is read in one call (:meth:`Transport.read_chunk`). Replies in the order
asked, each whole, are taken straight off the bytes; the first thing that is not that hands the
rest to :class:`PacketParser`, which copes with anything, so one silent or corrupt device costs
only its own data. The receive sleeps until the replies' wire time plus a learnt lateness
(:func:`next_lateness`), so a tick wakes once for its replies, not once per reply.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple, cast

import numpy as np

from robot_daemon.bus.packet import PACKET_OVERHEAD, Packet, PacketParser, instruction_packet
from robot_daemon.bus.tables import BROADCAST_ID, Instruction
from robot_daemon.bus.transport import Transport
from robot_daemon.hotpath import compiled as _compiled

if TYPE_CHECKING:
    from robot_daemon.bus.dxl import ReplyBudget

# The learnt lateness of a bulk read's replies: how fast it comes down after a read that was
# all in at once, and its ceiling (ms).
LATENESS_STEP_MS = 0.02
MAX_LATENESS_MS = 2.0


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
class BulkPlan:
    """One BULK_READ worked out once: its packet, the replies expected and how long each may
    take."""

    param: list[int]  # the BULK_READ parameters
    want: dict[int, int]  # id → data length
    order: list[int]  # ids in the order asked
    rank: dict[int, int]  # id → its place in ``order``
    waits: list[float]  # ms, each reply's own wait (wire time, return delay, margin)
    all_waits: float  # ms, their sum: the longest the transaction may take after the request
    wire: float  # ms, when every reply is in if all goes well (no margins)
    packet: bytes  # the BULK_READ instruction packet itself
    # (id, data length, FF FF ID LEN) in order: what an in-order answer looks like
    expect: list[tuple[int, int, bytes]]
    tail: list[int]  # bytes of the replies from each one in order to the end
    # The whole answer in order, read at once (the usual tick): each reply's header, error
    # byte and data out of the bytes in one call, and every checksum summed in another.
    replies: struct.Struct  # per reply: FF FF ID LEN (4s), ERR (B), data (Ns), CHK (x)
    headers: tuple[bytes, ...]  # what each header must be
    sum_at: np.ndarray  # reduceat bounds: ID…CHK of each reply, then the next one's FF FF
    sums_ok: bytes  # 0xFF for each reply: ID + LEN + ERR + data + CHK of a good one
    ids: tuple[int, ...]  # ``order`` and each one's data length, as the compiled take wants
    lengths: tuple[int, ...]

    @classmethod
    def make(
        cls, blocks: list[tuple[int, int, int]], budget: ReplyBudget, byte_ms: float
    ) -> BulkPlan:
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
        expect = [(i, want[i], bytes((0xFF, 0xFF, i, want[i] + 2))) for i in order]
        sizes = [want[i] + PACKET_OVERHEAD for i in order]
        tail = [sum(sizes[k:]) for k in range(len(sizes))]
        replies = struct.Struct("<" + "".join(f"4sB{want[i]}sx" for i in order))
        starts = [tail[0] - t for t in tail]
        bounds = [b for at, size in zip(starts, sizes, strict=True) for b in (at + 2, at + size)]
        return cls(
            param, want, order, rank, waits, sum(waits), wire, packet, expect, tail, replies,
            tuple(h for _, _, h in expect), np.array(bounds[:-1], np.intp), b"\xff" * len(order),
            tuple(order), tuple(want[i] for i in order),
        )


class Received(NamedTuple):
    missing: list[int]  # IDs whose data did not come
    heard: set[int]  # IDs heard at all (a garbled reply was still on the wire)
    woken: int  # reads it took
    seen_ms: float | None  # how much later than their wire time all were in (None: not all)


def receive(
    port: Transport, plan: BulkPlan, sent: float, late_ms: float, out: BulkResult
) -> Received:
    """The replies to one BULK_READ sent (its last byte on the wire at ``sent``, the
    transport's clock), into ``out``; ``late_ms``: how much later than their wire time they
    are expected all in."""
    want, order, rank, waits = plan.want, plan.order, plan.rank, plan.waits
    # Replies come in bus order, so each wait is for the next device due after the last one
    # heard: the first one after the instruction has crossed the wire, each later one after
    # the reply before it. Once a device is heard, the ones before it that were not never
    # will be: nobody waits for them. The whole transaction never takes longer than every
    # reply's own wait, however the replies trickle in.
    final = sent + plan.all_waits
    # When every reply should be in if all goes well (no margins): reads wait for that,
    # never past a deadline, so the loop wakes a few times per bulk read, not per reply.
    whole = sent + plan.wire + late_ms
    woken = 0  # reads since the expected time: one that finds everything in, we slept enough
    due = 0  # index in ``order`` of the next device waited for; len(order): none
    deadline = sent + waits[0]
    pending = set(order)
    heard: set[int] = set()
    data, errors = out.data, out.errors
    # Whatever has arrived is read in one call and every complete packet in it framed in
    # one pass: on an FTDI that is one wake-up per 62-byte USB packet, not one SDK round
    # trip (header, then body, each a read) per device.
    # Made when something is not the usual in-order answer (most ticks never need it).
    parser: PacketParser | None = None
    # The usual case costs one comparison per reply: replies in the order asked, each
    # whole, are taken straight off the bytes (``raw`` from ``pos``); the first thing that
    # is not that hands the rest to the parser, which copes with anything.
    raw = bytearray()
    pos = 0
    n = len(order)
    in_order = True
    while due < n:
        limit = min(deadline, final)
        target = min(whole, limit)
        port.idle_until(target)
        chunk = port.read_chunk(limit)
        # Only reads at the expected time teach the lateness: an earlier one, capped by the
        # due reply's deadline, says nothing of when the rest come.
        woken += target >= whole
        if not chunk:
            break  # the reply due is not coming
        if in_order:
            raw += chunk
            buf = bytes(raw)  # slices of bytes are the data as is; of a bytearray, a copy more
            have = len(buf)
            if due == 0 and have == plan.tail[0] and _take_whole(plan, buf, data, errors):
                pending.clear()
                heard.update(order)
                due, pos = n, have
            if due < n:
                first = due
                due, pos, in_order = _take_run(plan, buf, pos, due, data, errors)
                if due > first:
                    taken = order[first:due]
                    pending.difference_update(taken)
                    heard.update(taken)
            if in_order:
                if due < n:
                    now = port.getCurrentTime()
                    deadline = now + waits[due]
                    if now >= whole:
                        # Later than expected: the rest cannot be in before its bytes have
                        # crossed, so sleep that long rather than wake for every reply.
                        rest = plan.tail[due] - (have - pos)
                        whole = now + rest * port.tx_time_per_byte
                continue
            chunk = bytes(raw[pos:])
        if parser is None:
            parser = PacketParser()
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
    seen = port.getCurrentTime() - (sent + plan.wire) if in_order and due == n else None
    if in_order and len(raw) - pos >= 3 and raw[pos] == 0xFF and raw[pos + 1] == 0xFF:
        parser = parser or PacketParser()
        parser.feed(bytes(raw[pos : pos + 3]))  # a reply cut short: who was talking
    late = parser.pending_id if parser is not None else None
    if late is not None and late in want:
        heard.add(late)  # cut short on the wire: the device was still talking
    missing = [i for i in order if i in pending] if pending else []
    return Received(missing, heard, woken, seen)


def _take_run(
    plan: BulkPlan, buf: bytes, pos: int, due: int, data: dict[int, bytes],
    errors: dict[int, int],
) -> tuple[int, int, bool]:
    """:func:`_take_run_py`, by the compiled take where it is built (the same data, errors and
    answer, tests/unit/test_hotpath.py)."""
    if _compiled is not None:
        took = _compiled.take_run(buf, pos, due, plan.ids, plan.lengths, data, errors)
        if took is not NotImplemented:
            return cast("tuple[int, int, bool]", took)
    return _take_run_py(plan, buf, pos, due, data, errors)


def _take_run_py(
    plan: BulkPlan, buf: bytes, pos: int, due: int, data: dict[int, bytes],
    errors: dict[int, int],
) -> tuple[int, int, bool]:
    """The replies of ``plan`` from its ``due``-th on, at ``pos`` in ``buf``, each whole and
    in order, into ``data`` and ``errors``, up to the first not all in ``buf``: where the
    next one starts (its place in the order, its byte) and True; False at the first that is
    not a good reply (its header or checksum), which the parser then reads."""
    expect, n, have = plan.expect, len(plan.expect), len(buf)
    while due < n:
        dxl_id, length, header = expect[due]
        end = pos + length + PACKET_OVERHEAD
        if have < end:
            break
        # ID + LEN + ERR + data + checksum of a good packet sum to 0xFF (mod 256).
        if buf[pos : pos + 4] != header or sum(buf[pos + 2 : end]) & 0xFF != 0xFF:
            return due, pos, False
        data[dxl_id] = buf[pos + 5 : end - 1]
        if buf[pos + 4]:
            errors[dxl_id] = buf[pos + 4]
        due += 1
        pos = end
    return due, pos, True


def _take_whole(
    plan: BulkPlan, buf: bytes, data: dict[int, bytes], errors: dict[int, int]
) -> bool:
    """:func:`_take_whole_py`, by the compiled take where it is built (robot_daemon/hotpath.py:
    the same data, errors and verdict, tests/unit/test_hotpath.py)."""
    if _compiled is not None:
        took = _compiled.take_whole(buf, plan.ids, plan.lengths, data, errors)
        if took is not NotImplemented:
            return bool(took)
    return _take_whole_py(plan, buf, data, errors)


def _take_whole_py(
    plan: BulkPlan, buf: bytes, data: dict[int, bytes], errors: dict[int, int]
) -> bool:
    """Every reply of ``plan`` in order and whole in ``buf`` (exactly their bytes) into
    ``data`` and ``errors``, as the reply-by-reply loop would take them; False (nothing taken)
    when any header or checksum is not that of a good reply: the loop then finds which.
    Two C calls for the lot instead of a slice, a compare and a ``sum`` per reply."""
    fields = plan.replies.unpack(buf)
    if fields[0::3] != plan.headers:
        return False
    sums = np.add.reduceat(np.frombuffer(buf, np.uint8), plan.sum_at, dtype=np.uint8)
    if sums.tobytes()[0::2] != plan.sums_ok:
        return False
    data.update(zip(plan.order, fields[2::3], strict=True))
    errs = fields[1::3]
    if any(errs):
        errors.update((i, e) for i, e in zip(plan.order, errs, strict=True) if e)
    return True


def next_lateness(late_ms: float, woken: int, seen_ms: float) -> float:
    """The lateness to sleep for next time: a little less after a bulk read that was all in at
    the first read (it may have been in earlier), part of the way to what was seen after one
    that needed more reads. Bounded, so a stall does not make the loop sleep through its tick."""
    if woken <= 1:
        return max(0.0, late_ms - LATENESS_STEP_MS)
    return min(MAX_LATENESS_MS, late_ms + (max(seen_ms, late_ms) - late_ms) * 0.5)


def split_tail(
    blocks: list[tuple[int, int, int]], missing: list[int], heard: set[int]
) -> tuple[list[int], list[int]]:
    """The missing IDs before the last device heard, and those after it (in bus order)."""
    order = [b[0] for b in blocks]
    last = max((k for k, i in enumerate(order) if i in heard), default=-1)
    before = [i for i in missing if order.index(i) < last]
    return before, [i for i in missing if order.index(i) > last]


def blame(blocks: list[tuple[int, int, int]], missing: list[int], heard: set[int]) -> list[int]:
    before, tail = split_tail(blocks, missing, heard)
    return before + tail[:1]
