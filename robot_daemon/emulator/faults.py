"""Faults injected on replies: dropped, corrupted or delayed status packets.

Each reply draws from the emulator's seeded generator, so a run with the same seed and the same
traffic injects the same faults. How each one looks to the dynamixel-sdk:

* dropped: the device stays silent → ``COMM_RX_TIMEOUT``;
* corrupted: one byte after the ERR byte (a data byte or the checksum) is changed, so the frame
  keeps its length and the checksum fails → ``COMM_RX_CORRUPT``;
* delayed: the reply leaves ``delay_ms`` late (50 ms by default, past the SDK's ~34 ms packet
  timeout) → ``COMM_RX_TIMEOUT``; a reply still waiting when the host sends its next instruction
  collides with it on the half-duplex line and is lost.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Faults:
    """Faults the emulator injects in its replies: probabilities of a drop, a corruption, a
    delay."""

    drop: float = 0.0
    corrupt: float = 0.0
    delay: float = 0.0
    delay_ms: float = 50.0

    def __post_init__(self) -> None:
        self.check()

    def check(self) -> None:
        for name in ("drop", "corrupt", "delay"):
            p = getattr(self, name)
            if not 0.0 <= p <= 1.0:
                raise ValueError(f"fault probability {name}={p!r} is outside 0..1")
        if self.delay_ms < 0:
            raise ValueError(f"delay_ms={self.delay_ms!r} must be ≥ 0")

    @property
    def active(self) -> bool:
        """Any fault set: otherwise :meth:`apply` passes every packet as it is, drawing
        nothing from the generator."""
        return bool(self.drop or self.corrupt or self.delay)

    def apply(self, rng: np.random.Generator, packet: bytes) -> tuple[bytes | None, float, str]:
        """The packet as it goes out (None if dropped), extra delay in s, and the fault's name."""
        if self.drop and rng.random() < self.drop:
            return None, 0.0, "dropped"
        if self.corrupt and rng.random() < self.corrupt:
            index = int(rng.integers(5, len(packet)))
            flip = int(rng.integers(1, 256))
            out = bytearray(packet)
            out[index] ^= flip  # one byte changed: the checksum cannot match any more
            return bytes(out), 0.0, "corrupted"
        if self.delay and rng.random() < self.delay:
            return packet, self.delay_ms / 1000.0, "delayed"
        return packet, 0.0, ""
