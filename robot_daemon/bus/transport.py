"""The bus's one seam: how bytes reach the devices.

A :class:`Transport` is a dynamixel-sdk ``PortHandler`` (the SDK's ``Protocol1PacketHandler``
drives it: ``writePort``, ``readPort``, ``clearPort``, the packet timeout) plus what the bus
layer needs around it: open/close, byte counters, a clock the waits are measured on, and a
pause. Two exist: the serial port (:class:`robot_daemon.bus.port.BlockingPortHandler`) and an
in-process link to the emulator (:class:`robot_daemon.emulator.inprocess_link.EmulatorLink`);
the protocol code above them (:mod:`robot_daemon.bus.dxl`, :mod:`robot_daemon.bus.robot_bus`) is
the same.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod

from dynamixel_sdk import PortHandler

from schemas import units


class Transport(PortHandler, ABC):  # type: ignore[misc]  # dynamixel-sdk ships no types
    """Bytes in and out; subclasses implement the SDK's I/O hooks and :meth:`open`."""

    is_open: bool  # the SDK's PortHandler sets it

    def __init__(self, port_name: str) -> None:
        super().__init__(port_name)
        self.bytes_written = 0
        self.bytes_read = 0

    @abstractmethod
    def open(self, baudrate: int) -> None: ...

    @abstractmethod
    def close(self) -> None: ...

    def set_baud(self, baudrate: int) -> None:
        self.baudrate = baudrate
        self.tx_time_per_byte = units.wire_time_s(1, baudrate) * 1000.0  # ms, as the SDK keeps it

    def getCurrentTime(self) -> float:
        # Monotonic, in ms: the SDK's wall clock would jump with NTP.
        return time.monotonic() * 1000.0

    def pause(self, seconds: float) -> None:
        """Let ``seconds`` pass on the devices' clock (power-on waits)."""
        time.sleep(seconds)

    def latency_timer_ms(self) -> int | None:
        """The USB adapter's latency timer, if the transport has one."""
        return None

    def idle_until(self, clock_ms: float) -> None:
        """Do nothing on the bus until ``clock_ms`` (this transport's clock)."""
        wait = clock_ms - self.getCurrentTime()
        if wait > 0:
            time.sleep(wait / 1000.0)

    def read_chunk(self, deadline_ms: float) -> bytes:
        """Whatever has arrived, waiting for it until ``deadline_ms`` (this transport's clock):
        b"" when nothing came by then. The bulk read's receive path: one call per arriving
        chunk (a USB packet on an FTDI, a write on the emulator's pty), not one per packet."""
        self.setPacketTimeoutMillis(deadline_ms - self.getCurrentTime())
        chunk: bytes = self.readPort(4096)
        return chunk
