"""The versions on the wire: the package's and the protocol's, and the one check every client
runs on the daemon's announcement (its ``status``: ``version`` and ``protocol``).

``PROTOCOL_VERSION = (major, minor)``: the major is the messages' schema version (a message of
another major does not decode, :func:`schemas.messages.decode`); the minor counts additive
changes (a new field, a new verb), which a client of another minor still understands, so a minor
skew is a warning and a major one a refusal naming both versions and what to upgrade.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

from schemas import SCHEMA_VERSION
from schemas.errors import ConfigError, IncompatibleProtocolError

# 1.1: status carries version, protocol, power and heat.
# 2.0: joints carry radians only (no position_deg); a 1.x client is refused in one line.
# 2.1: policy_status carries `lost` (actions of the stream lost on the way).
PROTOCOL_VERSION: tuple[int, int] = (SCHEMA_VERSION, 1)
PACKAGE = "darwin-zenoh"
# The package's version, defined here once: pyproject.toml reads it ([tool.setuptools.dynamic]),
# so the installed metadata says the same, and a program announces it without importing
# importlib.metadata (60 ms of CPU at each daemon start) or being installed at all.
PACKAGE_VERSION = "0.1.0"
# A daemon from before versions were announced: protocol 1.0.
UNANNOUNCED: tuple[int, int] = (1, 0)
# What the daemon announces instead of PROTOCOL_VERSION ("MAJOR.MINOR"): for testing clients
# against another protocol without building another daemon.
ENV_ANNOUNCE = "DARWIN_ANNOUNCE_PROTOCOL"


def parse_protocol(text: str) -> tuple[int, int]:
    major, sep, minor = text.strip().partition(".")
    if not (sep and major.isdigit() and minor.isdigit()):
        raise ValueError(f"protocol version {text!r} should be MAJOR.MINOR, e.g. 2.0")
    return int(major), int(minor)


def announced_protocol() -> tuple[int, int]:
    """The protocol the daemon announces (PROTOCOL_VERSION unless ``DARWIN_ANNOUNCE_PROTOCOL``)."""
    override = os.environ.get(ENV_ANNOUNCE)
    if not override:
        return PROTOCOL_VERSION
    try:
        return parse_protocol(override)
    except ValueError as exc:
        raise ConfigError(
            f"{ENV_ANNOUNCE}: {exc}; unset it to announce {fmt(PROTOCOL_VERSION)}"
        ) from None


def fmt(protocol: tuple[int, int]) -> str:
    return f"{protocol[0]}.{protocol[1]}"


def announcement(status: Mapping[str, Any]) -> tuple[tuple[int, int], str]:
    """(protocol, package version) from a status map (decoded or raw msgpack)."""
    raw = status.get("protocol")
    protocol = UNANNOUNCED
    if isinstance(raw, list | tuple) and len(raw) == 2 and all(isinstance(v, int) for v in raw):
        protocol = (int(raw[0]), int(raw[1]))
    version = status.get("version")
    return protocol, version if isinstance(version, str) and version else "unknown"


def check_daemon(status: Mapping[str, Any], program: str) -> str | None:
    """Check the daemon's announcement against this client (``program``: e.g. ``darwin tui``).

    None when both speak the same protocol; a one-line warning on a minor skew; raises
    :class:`IncompatibleProtocolError` (one line, both versions, what to upgrade) on another
    major."""
    theirs, their_version = announcement(status)
    ours = PROTOCOL_VERSION
    if theirs == ours:
        return None
    robot = status.get("robot") or "?"
    both = (
        f"{program} speaks protocol {fmt(ours)} ({PACKAGE} {PACKAGE_VERSION}), the daemon of "
        f"robot {robot} speaks {fmt(theirs)} ({PACKAGE} {their_version})"
    )
    newer = "the robot's daemon" if theirs < ours else "this client"
    if theirs[0] != ours[0]:
        raise IncompatibleProtocolError(
            f"{both}: incompatible; upgrade {newer} (git pull in its clone, then pip install "
            f"it again) so both speak protocol {max(theirs, ours)[0]}.x "
            "(docs/troubleshooting.md#version-skew)"
        )
    return f"{both}: it works, but upgrade {newer} for the newer fields and verbs"
