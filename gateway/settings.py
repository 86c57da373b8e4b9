"""The gateway's settings: ``[gateway]`` in config/gateway.toml, a user file, then the CLI."""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from typing import Any

from clients.listen import parse_listen as _parse_listen
from config.loader import load_section, section_to
from gateway.framing import MAX_DEPTH_LIMIT, MAX_NUMBER_LENGTH_LIMIT, BodyLimits
from schemas.errors import ConfigError


@dataclass(frozen=True)
class WalkMapping:
    """Legacy walk units (ROBOTIS step amplitudes) to the walk verb's SI units."""

    x_mps_per_unit: float = 0.0066667
    y_mps_per_unit: float = 0.0033333
    a_radps_per_unit: float = 0.0581776


@dataclass(frozen=True)
class GatewaySettings:
    listen: str = "127.0.0.1:9000"
    max_message: int = 1 << 20
    max_partial_frame: int = 65536
    max_depth: int = BodyLimits.max_depth
    max_number_length: int = BodyLimits.max_number_length
    max_connections: int = 200
    idle_timeout: float = 60.0
    monitor_period: float = 0.1
    max_rate: float = 200.0
    burst: int = 50
    lease_idle_timeout: float = 30.0
    command_timeout: float = 3.0
    workers: int = 16
    write_buffer: int = 65536
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


# Settings that must lie in a range: (low, high); None = no upper bound.
RANGES: dict[str, tuple[float, float | None]] = {
    "max_message": (1, None),
    "max_partial_frame": (1, None),
    "max_depth": (1, MAX_DEPTH_LIMIT),
    "max_number_length": (1, MAX_NUMBER_LENGTH_LIMIT),
    "max_connections": (1, None),
    "idle_timeout": (0, None),
    "lease_idle_timeout": (0, None),
    "monitor_period": (1e-3, None),
    "max_rate": (1e-3, None),
    "burst": (1, None),
    "workers": (1, None),
    "write_buffer": (1, None),
}


def check_settings(settings: GatewaySettings) -> GatewaySettings:
    """``settings`` when every value is usable (after the config files and the command line)."""
    parse_listen(settings.listen)
    for name, (low, high) in RANGES.items():
        value = getattr(settings, name)
        if value < low or (high is not None and value > high):
            bound = f"at least {low:g}" if high is None else f"within {low:g}..{high:g}"
            raise ConfigError(f"[gateway] {name} must be {bound}, not {value!r}")
    return settings
