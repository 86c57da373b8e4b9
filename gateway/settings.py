"""The gateway's settings: ``[gateway]`` in config/gateway.toml, a user file, then the CLI."""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from typing import Any

from clients.listen import parse_listen as _parse_listen
from config.loader import check_ranges, load_section, ranged, section_to
from gateway.framing import MAX_DEPTH_LIMIT, MAX_NUMBER_LENGTH_LIMIT, BodyLimits


@dataclass(frozen=True)
class WalkMapping:
    """Legacy walk units (ROBOTIS step amplitudes) to the walk verb's SI units."""

    x_mps_per_unit: float = 0.0066667
    y_mps_per_unit: float = 0.0033333
    a_radps_per_unit: float = 0.0581776


@dataclass(frozen=True)
class GatewaySettings:
    """The ``[gateway]`` section: where it listens, what a client may send, and its timeouts."""

    listen: str = "127.0.0.1:9000"
    max_message: int = ranged(1 << 20, 1)
    max_partial_frame: int = ranged(65536, 1)
    max_depth: int = ranged(BodyLimits.max_depth, 1, MAX_DEPTH_LIMIT)
    max_number_length: int = ranged(BodyLimits.max_number_length, 1, MAX_NUMBER_LENGTH_LIMIT)
    max_connections: int = ranged(200, 1)
    idle_timeout: float = ranged(60.0, 0)
    monitor_period: float = ranged(0.1, 1e-3)
    max_rate: float = ranged(200.0, 1e-3)
    burst: int = ranged(50, 1)
    lease_idle_timeout: float = ranged(30.0, 0)
    command_timeout: float = 3.0
    workers: int = ranged(16, 1)
    write_buffer: int = ranged(65536, 1)
    socket_send_buffer: int = 0
    max_pending_replies: int = 256
    operate_all_duration: float = 1.0
    log_interval: float = 5.0
    walk: WalkMapping = WalkMapping()

    @property
    def host_port(self) -> tuple[str, int]:
        return parse_listen(self.listen)

    @property
    def max_incoming(self) -> int:
        """The most bytes a client's message may announce (and so park while incomplete)."""
        return min(self.max_message, self.max_partial_frame)

    @property
    def body_limits(self) -> BodyLimits:
        return BodyLimits(self.max_depth, self.max_number_length)

    def with_overrides(self, **values: Any) -> GatewaySettings:
        return replace(self, **{k: v for k, v in values.items() if v is not None})


def parse_listen(listen: str) -> tuple[str, int]:
    return _parse_listen(listen, "gateway", "127.0.0.1:9000")


def load_settings(path: str | os.PathLike[str] | None = None) -> GatewaySettings:
    settings = section_to(GatewaySettings, load_section("gateway", path), "gateway")
    return check_settings(settings)


def check_settings(settings: GatewaySettings) -> GatewaySettings:
    """``settings`` when every value is usable (after the config files and the command line)."""
    parse_listen(settings.listen)
    check_ranges(settings, "gateway")
    return settings
