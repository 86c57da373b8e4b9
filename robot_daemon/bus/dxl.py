"""Dynamixel Protocol 1.0 transactions over dynamixel-sdk: read, write, sync write, bulk read.

The bulk read sends its packet through the SDK's ``bulkReadTx`` (``GroupBulkRead`` in 3.8.4 …
4.1.0 cannot on Protocol 1.0: it passes an argument ``bulkReadTx`` does not take) and receives
with the SDK's ``rxPacket`` one status packet at a time, so one silent or corrupt device costs
only its own data: every packet that does arrive is kept, matched by ID.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TypeVar

from dynamixel_sdk import COMM_RX_CORRUPT, COMM_SUCCESS, Protocol1PacketHandler

from robot_daemon.bus.port import BlockingPortHandler
from robot_daemon.bus.tables import BROADCAST_ID, ErrorBit
from schemas.errors import BusError, NoReplyError, PacketError, PortError

T = TypeVar("T")

# Packet overhead: FF FF ID LEN INST/ERR … CHK.
_OVERHEAD = 6


def error_names(bits: int) -> list[str]:
    return [b.name.lower() for b in ErrorBit if bits & b]


@dataclass
class BulkResult:
    """Data of one bulk read: id → bytes for every device that answered correctly."""

    data: dict[int, bytes] = field(default_factory=dict)
    errors: dict[int, int] = field(default_factory=dict)  # id → error bits of its status packet
    missing: list[int] = field(default_factory=list)  # no reply
    corrupt: int = 0  # packets dropped for a bad checksum or length
    retried: bool = False
    stalled: bool = False  # nothing answered at all


class DxlBus:
    """Transactions on one open port. Not thread-safe: one thread (the motion loop) owns it."""

    def __init__(self, port: BlockingPortHandler, gap_ms: float = 2.0) -> None:
        self.port = port
        self.ph = Protocol1PacketHandler()
        # Once replies flow, the next one is due within its own wire time: a device that has
        # not answered ``gap_ms`` after that is taken as silent, so a dropped reply costs a
        # couple of ms instead of the whole reply margin.
        self.gap_ms = gap_ms

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

    # -- single-device transactions -----------------------------------------------------------
    def ping(self, dxl_id: int) -> bool:
        _, result, _ = self.ph.txRxPacket(self.port, [0, 0, dxl_id, 2, 1, 0])
        return result == COMM_SUCCESS

    def read(self, dxl_id: int, address: int, length: int, tries: int = 1) -> tuple[bytes, int]:
        """Read ``length`` bytes; returns (data, error bits) or raises ``BusError``. A missing or
        corrupt reply is asked for again, ``tries`` times in all; a lost port is not."""
        return _retry(tries, lambda: self._read_once(dxl_id, address, length))

    def _read_once(self, dxl_id: int, address: int, length: int) -> tuple[bytes, int]:
        result = self.ph.readTx(self.port, dxl_id, address, length)
        self._check(result, f"READ {address}+{length}", dxl_id)
        # The SDK takes any packet from that ID; a late reply to an earlier transaction (a bulk
        # read that timed out) would pass for this one. Only a reply of the right length counts.
        while True:
            rx, result = self.ph.rxPacket(self.port)
            self._check(result, f"READ {address}+{length}", dxl_id)
            if rx[2] == dxl_id and rx[3] == length + 2:
                return bytes(rx[5 : 5 + length]), rx[4]

    def write(self, dxl_id: int, address: int, data: bytes, tries: int = 1) -> int:
        """WRITE and wait for the status packet; returns its error bits. Retried like
        :meth:`read` (writing the same value again is harmless)."""
        return _retry(tries, lambda: self._write_once(dxl_id, address, data))

    def _write_once(self, dxl_id: int, address: int, data: bytes) -> int:
        result, error = self.ph.writeTxRx(self.port, dxl_id, address, len(data), list(data))
        self._check(result, f"WRITE {address}+{len(data)}", dxl_id)
        return error

    def write_no_reply(self, dxl_id: int, address: int, data: bytes) -> None:
        self.ph.writeTxOnly(self.port, dxl_id, address, len(data), list(data))
        self.port.is_using = False

    # -- group transactions -------------------------------------------------------------------
    def sync_write(self, start: int, length: int, rows: dict[int, bytes]) -> int:
        """SYNC_WRITE ``length`` bytes from ``start`` to each id in ``rows``; returns bytes sent."""
        if not rows:
            return 0
        param: list[int] = []
        for dxl_id, data in rows.items():
            if len(data) != length:
                raise ValueError(f"sync write row for {dxl_id} has {len(data)} bytes, not {length}")
            param.append(dxl_id)
            param.extend(data)
        result = self.ph.syncWriteTxOnly(self.port, start, length, param, len(param))
        if result != COMM_SUCCESS:
            raise BusError(f"SYNC_WRITE on {self.name} failed: {self.ph.getTxRxResult(result)}")
        return len(param) + 8

    def bulk_read(self, blocks: Iterable[tuple[int, int, int]]) -> BulkResult:
        """BULK_READ ``(id, start, length)`` blocks; every reply that arrives is kept."""
        blocks = list(blocks)
        out = BulkResult()
        if not blocks:
            return out
        missing = self._bulk_once(blocks, out)
        if not out.data and not out.corrupt:
            # Not one byte came back: the bus (or the adapter) stalled, not a device. Every
            # reading is stale this tick; nobody is blamed.
            out.stalled = True
        elif missing:
            # On the real bus a device waits for the one before it, so a silent device silences
            # the rest: ask again for the missing ones, the first silent one last so that, if
            # it is still silent, it delays nobody.
            again = [b for b in blocks if b[0] in missing[1:]]
            again += [b for b in blocks if b[0] == missing[0]]
            out.retried = True
            missing = self._bulk_once(again, out)
        out.missing = missing
        return out

    def _bulk_once(self, blocks: list[tuple[int, int, int]], out: BulkResult) -> list[int]:
        param: list[int] = []
        for dxl_id, start, length in blocks:
            param += [length, dxl_id, start]
        result = self.ph.bulkReadTx(self.port, param, len(param))
        if result != COMM_SUCCESS:
            raise BusError(f"BULK_READ on {self.name} failed: {self.ph.getTxRxResult(result)}")
        want = {dxl_id: length for dxl_id, _, length in blocks}
        per_byte = self.port.tx_time_per_byte
        reply_bytes = sum(length + _OVERHEAD for length in want.values())
        tx_bytes = len(param) + 7
        now = time.monotonic() * 1000.0
        # The whole transaction: the instruction and every reply on the wire, plus the margin.
        final = now + per_byte * (tx_bytes + reply_bytes) + self.port.reply_margin_ms
        # The first reply may take the full latency margin; later ones follow within a gap.
        deadline = now + per_byte * (tx_bytes + max(want.values()) + _OVERHEAD)
        deadline += self.port.reply_margin_ms
        longest = max(want.values()) + _OVERHEAD
        pending = set(want)
        while pending:
            remaining = min(deadline, final) - time.monotonic() * 1000.0
            if remaining <= 0:
                break
            self.port.setPacketTimeoutMillis(remaining)
            self.port.is_using = True
            rx, result = self.ph.rxPacket(self.port)
            if result == COMM_SUCCESS:
                dxl_id = rx[2]
                length = want.get(dxl_id)
                if dxl_id in pending and length is not None and rx[3] == length + 2:
                    out.data[dxl_id] = bytes(rx[5 : 5 + length])
                    if rx[4]:
                        out.errors[dxl_id] = rx[4]
                    pending.discard(dxl_id)
                else:
                    out.corrupt += 1
            elif result == COMM_RX_CORRUPT:
                out.corrupt += 1
            else:
                break  # timeout: nothing more is coming
            deadline = time.monotonic() * 1000.0 + per_byte * longest + self.gap_ms
        self.port.is_using = False
        return [b[0] for b in blocks if b[0] in pending]


def broadcast_ping_ids(bus: DxlBus, ids: Iterable[int]) -> list[int]:
    """IDs among ``ids`` that answer a PING (one at a time: Protocol 1.0 has no broadcast ping)."""
    return [i for i in ids if i != BROADCAST_ID and bus.ping(i)]


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
