"""Replies as an FTDI USB-serial chip hands them to the host: 62-byte USB packets, and what is
left when the latency timer fires.

The CM-730 reaches the robot's PC through an FTDI FT232R. Its receive buffer goes to the host
in 64-byte USB bulk packets, two bytes of which are modem status, so at most 62 data bytes per
packet; a packet leaves as soon as it is full, and a partly filled buffer leaves when the
latency timer (``/sys/bus/usb-serial/devices/ttyUSB0/latency_timer``, 16 ms by default, 1 ms
as the README sets it) runs out (FTDI application note AN232B-04, "Data Throughput, Latency
and Handshaking"). So a 21-reply bulk read of ~280 bytes reaches the host as four or five
full packets while the replies cross the wire and a last partial one a latency timer after
its first byte: a handful of wake-ups, where the emulator's default (each reply written to
the pty when its last byte is on the wire) gives 21.

The model: byte ``k`` of a reply whose last byte is on the wire at ``t`` arrives in the chip
at ``t - (n-1-k) × byte time``; a partial buffer is flushed ``latency`` after its first byte
came in. The flush of a partial buffer left at the end of one host transaction is scheduled
then (a host does not talk again while it waits for replies).
"""

from __future__ import annotations

# An FT232R bulk-in packet: 64 bytes, the first two the modem status.
USB_PACKET_BYTES = 62


class FtdiChip:
    """Turns replies ``(t_last_byte_on_wire, bytes)`` into USB deliveries ``(t, bytes)``."""

    def __init__(self, byte_s: float, latency_s: float, packet_bytes: int = USB_PACKET_BYTES):
        if latency_s <= 0:
            raise ValueError(f"FTDI latency timer must be above 0 ms, not {latency_s * 1000:g}")
        self.byte_s = byte_s
        self.latency_s = latency_s
        self.packet_bytes = packet_bytes

    def deliver(self, replies: list[tuple[float, bytes]]) -> list[tuple[float, bytes]]:
        # Every bulk read's 21 replies come through here: locals, and no min/max calls; the
        # timer's deadline (``first + latency``) and the buffer's length kept as they change.
        out: list[tuple[float, bytes]] = []
        buf = bytearray()
        fill = 0  # len(buf)
        first = 0.0  # when the first byte in ``buf`` came in
        deadline = latency = self.latency_s  # first + latency
        size, byte_s = self.packet_bytes, self.byte_s
        for t_end, packet in replies:
            n = len(packet)
            t0 = t_end - (n - 1) * byte_s  # byte 0 of this reply in the chip
            # Most replies join the buffer whole, before it fills or its timer fires: the
            # loop's first round below, decided with the same sums, and done in one step.
            if fill and t0 > deadline:
                out.append((deadline, bytes(buf)))
                buf.clear()
                fill = 0
            if not fill:
                first = t0
                deadline = first + latency
            # (The timer's margin here is never below 0, so a float compared with n - 1
            # decides as its int() would.)
            if fill + n < size and (not byte_s or (deadline - t0) / byte_s >= n - 1):
                buf += packet
                fill += n
                continue
            i = 0
            while i < n:
                t_i = t0 + i * byte_s
                if fill and t_i > deadline:
                    out.append((deadline, bytes(buf)))
                    buf.clear()
                    fill = 0
                if not fill:
                    first = t_i
                    deadline = first + latency
                # Bytes from i on that come in before the timer fires, up to a full packet.
                take = size - fill
                if n - i < take:
                    take = n - i
                if byte_s:
                    by_timer = int((deadline - t_i) / byte_s) + 1
                    if by_timer < take:
                        take = by_timer
                if take < 1:
                    take = 1
                buf += packet[i : i + take]
                fill += take
                i += take
                if fill >= size:
                    out.append((t0 + (i - 1) * byte_s, bytes(buf)))
                    buf.clear()
                    fill = 0
        if buf:
            out.append((deadline, bytes(buf)))
        return out
