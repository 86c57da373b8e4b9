"""The in-process transport: the bus layer talking to an :class:`Emulator` without a pty.

:class:`EmulatorLink` is a :class:`~robot_daemon.bus.transport.Transport`: the daemon's own
protocol code (dynamixel-sdk's packet handler, :mod:`robot_daemon.bus.dxl`,
:class:`~robot_daemon.bus.robot_bus.RobotBus`) runs above it unchanged, and below it the bytes go
straight to the emulator's packet handling (:meth:`Emulator.exchange`: parser, devices, faults).

Time on the link is its own clock (ms), moved only by waiting: the host's bytes take 10 µs each
at 1 Mbps behind what is still on the wire, a reply arrives when the emulator's wire model
says, and a wait for a reply that never comes ends at the wait's deadline. So a simulated tick
costs no wall-clock waiting, and how long the bus layer waits is exact and repeatable (a test
can count it). :meth:`pause` moves the
emulator's clock (a power-on wait); the physics is otherwise advanced by whoever owns the
emulator (:meth:`Emulator.advance`).
"""

from __future__ import annotations

from collections import deque

from robot_daemon.bus.packet import PacketParser
from robot_daemon.bus.transport import Transport
from robot_daemon.emulator.emulator import Emulator

# A wait ends just past its deadline: the SDK's timeout test is "elapsed > timeout".
_PAST_MS = 1e-6
# Arrival times are sums of byte times in seconds, the host's clock sums in ms: a reply due at
# the very moment the host looks may compare a rounding error later (1e-13 ms) and cost it a
# whole extra wait. Nothing on the wire is timed finer than this.
_SAME_MS = 1e-9


class EmulatorLink(Transport):
    def __init__(self, emulator: Emulator, name: str = "emulator") -> None:
        super().__init__(f"in-process:{name}")
        self.emulator = emulator
        self.clock_ms = 0.0
        self._parser = PacketParser()
        self._in_flight: deque[tuple[float, bytes]] = deque()  # (arrival ms, packet)
        self._rx = bytearray()  # arrived, not read yet
        self._wire_free = 0.0  # when the last byte written (or replied) has crossed

    def open(self, baudrate: int) -> None:
        self.set_baud(baudrate)
        self._parser.reset()
        self._in_flight.clear()
        self._rx.clear()
        self.is_open = True

    def close(self) -> None:
        self.is_open = False
        self._in_flight.clear()
        self._rx.clear()

    def getCurrentTime(self) -> float:
        return self.clock_ms

    def pause(self, seconds: float) -> None:
        self.clock_ms += seconds * 1000.0
        self.emulator.advance(seconds)

    def idle_until(self, clock_ms: float) -> None:
        """The host does nothing on the bus until ``clock_ms`` (the rest of its tick)."""
        self.clock_ms = max(self.clock_ms, clock_ms)

    def _arrive(self) -> None:
        while self._in_flight and self._in_flight[0][0] <= self.clock_ms + _SAME_MS:
            self._rx += self._in_flight.popleft()[1]

    # -- the SDK's I/O hooks ---------------------------------------------------------------
    def writePort(self, packet: list[int] | bytes) -> int:
        data = bytes(packet)
        self._arrive()
        if self._in_flight:
            # The host talks while a reply is still on its way: on a half-duplex line they
            # collide and the reply is lost (as the emulator's pty side models it).
            with self.emulator.lock:
                self.emulator.stats["collisions"] += len(self._in_flight)
            self._in_flight.clear()
        # As on a serial port, the write returns at once; the bytes cross the wire behind
        # whatever is still crossing it.
        start = max(self.clock_ms, self._wire_free)
        replies, end = self.emulator.exchange(self._parser, data, start / 1000.0)
        self._in_flight.extend((t * 1000.0, reply) for t, reply in replies)
        self._wire_free = end * 1000.0
        self.bytes_written += len(data)
        return len(data)

    def readPort(self, length: int) -> bytes:
        self._arrive()
        if not self._rx:
            # Wait, as select would: for the next reply if it comes before the deadline, else
            # until the deadline.
            deadline = self.packet_start_time + self.packet_timeout
            if self._in_flight and self._in_flight[0][0] <= deadline:
                self.clock_ms = max(self.clock_ms, self._in_flight[0][0])
                self._arrive()
            else:
                self.clock_ms = max(self.clock_ms, deadline + _PAST_MS)
                return b""
        data = bytes(self._rx[:length])
        del self._rx[:length]
        self.bytes_read += len(data)
        return data

    def clearPort(self) -> None:
        self._arrive()
        self._rx.clear()
