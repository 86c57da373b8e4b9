"""Limits that keep clients from starving the motion loop: per-client token buckets and the
per-tick work budget, from ``[daemon.arbiter]`` in ``config/daemon.toml``.

A client id is whatever the caller says, so the buckets are fairness between well-behaved
clients; what protects the tick against anyone is the bounded queue and the per-tick budget.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

from config.loader import section_to
from schemas.errors import ConfigError


@dataclass(frozen=True)
class ArbiterLimits:
    """How much the command side may take from the motion loop: sizes, rates and per-tick
    budgets."""

    max_payload_bytes: int = 64 * 1024  # refused before decoding
    queue_size: int = 64  # commands waiting for the motion thread; more are rate_limited
    commands_per_tick: int = 8  # at most this many commands per tick…
    work_budget_ms: float = 2.0  # …and no new one once this much of the tick went to commands
    bus_commands_per_tick: int = 1  # commands that are bus transactions (registers, torque, led)
    bus_time_share: float = 0.01  # of wall time, for client register reads (measured)…
    bus_burst_ms: float = 3.0  # …saved up to this much
    client_rate: float = 50.0  # commands/s per client (token bucket)…
    client_burst: int = 25  # …with this many at once
    client_read_rate: float = 20.0  # `registers` reads/s per client…
    client_read_burst: int = 5
    reply_timeout: float = 5.0  # a command the loop did not take by then gets `unavailable`

    @classmethod
    def from_config(cls, section: dict[str, Any]) -> ArbiterLimits:
        limits = section_to(cls, section, "daemon.arbiter")
        for f in fields(cls):
            if getattr(limits, f.name) <= 0:
                raise ConfigError(f"[daemon.arbiter] {f.name} must be a positive number")
        return limits


class Buckets:
    """One token bucket per key; the least recently used keys are forgotten past ``max_keys``
    (a forgotten key starts again with a full bucket, which costs nothing dangerous)."""

    def __init__(
        self,
        rate: float,
        burst: int,
        max_keys: int = 1024,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.rate = rate
        self.burst = float(burst)
        self.max_keys = max_keys
        self._clock = clock
        self._state: OrderedDict[str, tuple[float, float]] = OrderedDict()

    def take(self, key: str) -> float:
        """Take one token: 0.0 when allowed, else the seconds until one is available."""
        now = self._clock()
        tokens, last = self._state.pop(key, (self.burst, now))
        tokens = min(self.burst, tokens + (now - last) * self.rate)
        wait = 0.0
        if tokens >= 1.0:
            tokens -= 1.0
        else:
            wait = (1.0 - tokens) / self.rate
        self._state[key] = (tokens, now)
        while len(self._state) > self.max_keys:
            self._state.popitem(last=False)
        return wait
