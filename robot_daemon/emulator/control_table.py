"""A device's control table in memory: bytes, register layout, access rules and range checks.

The layout comes from :mod:`robot_daemon.bus.tables`. Error bits a WRITE can earn, as this
emulator decides them (the Protocol 1.0 e-manual names the bits but not every case):

* value of a register outside its range, write to a read-only register, write past the end
  of the table, EEPROM write while LOCK is set: **RANGE (0x08)**, and nothing of the packet is
  written (a write is all or nothing);
* MX-28 goal position outside the CW..CCW angle limits: **ANGLE_LIMIT (0x02)**, not written;
* addresses that are not in the table (reserved bytes such as the MX-28's 29, which the
  framework sync-writes as 0 every tick) accept any value and read back 0.
"""

from __future__ import annotations

from enum import Enum

from robot_daemon.bus.tables import Access, ErrorBit, Register


class ControlTable:
    """Indexed by the members of the register enum it was made from (``table[MX28.ID]``)."""

    def __init__(self, registers: type[Enum], size: int) -> None:
        self.size = size
        self.kind = registers
        self.registers: dict[Enum, Register] = {m: m.value for m in registers}
        self._by_address: dict[int, tuple[Enum, Register]] = {}
        for member, reg in self.registers.items():
            for a in range(reg.address, reg.end):
                self._by_address[a] = (member, reg)
        self.data = bytearray(size)
        # (address, length) of a write → the registers it touches (check_write)
        self._touched: dict[tuple[int, int], list[tuple[Register, int, int, bool, bool, int, int]]]
        self._touched = {}
        self.reset()

    def reset(self, eeprom: bool = True) -> None:
        """Defaults of every register (RAM only when ``eeprom`` is false, as at power-on)."""
        for reg in self.registers.values():
            if reg.default is not None and (eeprom or not reg.eeprom):
                self.put(reg, reg.default)

    # ---- raw access (the device model uses these; no checks) -------------------------------

    def get(self, reg: Register) -> int:
        a = reg.address
        if reg.size == 1:
            return self.data[a]
        return self.data[a] | (self.data[a + 1] << 8)

    def put(self, reg: Register, value: int) -> None:
        a, v = reg.address, int(value)
        self.data[a] = v & 0xFF
        if reg.size == 2:
            self.data[a + 1] = (v >> 8) & 0xFF

    # The device model reads and writes a dozen registers per servo per step, hundreds of steps
    # a second: a member's register is taken off it (``_value_``) rather than looked up by the
    # member, whose hash is Python code in ``enum``.
    def __getitem__(self, member: Enum) -> int:
        if type(member) is not self.kind:
            raise KeyError(member)
        reg: Register = member._value_
        a = reg.address
        if reg.size == 1:
            return self.data[a]
        return self.data[a] | (self.data[a + 1] << 8)

    def __setitem__(self, member: Enum, value: int) -> None:
        if type(member) is not self.kind:
            raise KeyError(member)
        reg: Register = member._value_
        a, v = reg.address, int(value)
        self.data[a] = v & 0xFF
        if reg.size == 2:
            self.data[a + 1] = (v >> 8) & 0xFF

    # ---- bus access --------------------------------------------------------------------------

    def read(self, address: int, length: int) -> tuple[bytes, int]:
        """Bytes for a READ and the error bits: past the end reads as zeros with RANGE set."""
        end = address + length
        if length and end <= self.size:
            return bytes(self.data[address:end]), 0
        if address >= self.size or length == 0:
            return bytes(length), ErrorBit.RANGE
        end = min(address + length, self.size)
        data = bytes(self.data[address:end]) + bytes(address + length - end)
        return data, (ErrorBit.RANGE if end < address + length else 0)

    def check_write(
        self, address: int, data: bytes, eeprom_locked: bool = False
    ) -> tuple[list[tuple[Register, int]], int]:
        """Validate a WRITE: the registers it changes with their new values, and error bits.

        On any error bit the list is empty: the caller writes nothing.
        """
        if not data or address + len(data) > self.size:
            return [], ErrorBit.RANGE
        span = (address, len(data))
        touched = self._touched.get(span)
        if touched is None:
            touched = self._touched[span] = self._registers_in(address, len(data))
        image = bytearray(self.data)
        image[address : address + len(data)] = data
        changes: list[tuple[Register, int]] = []
        for reg, start, end, read_only, eeprom, low, high in touched:
            if read_only or (eeprom and eeprom_locked):
                return [], ErrorBit.RANGE
            value = int.from_bytes(image[start:end], "little")
            if not low <= value <= high:
                return [], ErrorBit.RANGE
            changes.append((reg, value))
        return changes, 0

    def _registers_in(
        self, address: int, length: int
    ) -> list[tuple[Register, int, int, bool, bool, int, int]]:
        """The registers a write of ``length`` bytes at ``address`` touches, in address order
        (each once), with what :meth:`check_write` asks of each: found once for each span (20
        goals a tick while the robot moves, each looking its registers up by their members,
        whose hash is Python code in ``enum``)."""
        registers = []
        seen: set[Enum] = set()
        for a in range(address, address + length):
            entry = self._by_address.get(a)
            if entry is None or entry[0] in seen:
                continue
            seen.add(entry[0])
            reg = entry[1]
            read_only = reg.access is Access.R
            registers.append((reg, reg.address, reg.end, read_only, reg.eeprom, reg.low, reg.high))
        return registers
