"""Where TLS material lives, and how private files are written: what the daemon, the router and
``darwin users`` need without the ``cryptography`` package (the ``security`` extra), which only
creating certificates (``robot_daemon.security.certs``) imports. The daemon serves TLS from
certificates made elsewhere (``darwin certs`` on a laptop) with Zenoh alone."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class CertPaths:
    """Where ``darwin certs`` puts one certificate and its key."""

    cert: Path
    key: Path


def ca_paths(directory: Path) -> CertPaths:
    return CertPaths(directory / "ca.pem", directory / "ca.key")


def robot_paths(directory: Path) -> CertPaths:
    return CertPaths(directory / "robot.pem", directory / "robot.key")


def client_paths(directory: Path, user: str) -> CertPaths:
    return CertPaths(directory / f"{user}.pem", directory / f"{user}.key")


def write_private(path: Path, data: bytes) -> None:
    """Write ``data`` so that only the owner can ever read it (created 0600, not chmod later)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.unlink(missing_ok=True)
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.replace(tmp, path)
