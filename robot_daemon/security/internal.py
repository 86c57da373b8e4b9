"""Identities ``darwin up`` makes for its own adapters (gateway, ros2, foxglove, web, the UI) when
it runs with ``--auth``/``--secure``: each logs in as ``darwin-<name>``, with the role it needs
(``robot_daemon.launch.adapter_logins``), and a random password (or,
with ``--mtls``, a client certificate from the installation's CA), written 0600 in a private
directory that goes when ``darwin up`` stops. The daemon reads the people's identities plus
these (a merged identities file in the same directory)."""

from __future__ import annotations

import secrets
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from robot_daemon.security import users
from robot_daemon.security.acl import Security
from robot_daemon.security.paths import ca_paths, client_paths, write_private
from schemas.roles import Role


@dataclass
class Internal:
    """The identities of one ``darwin up``'s adapters, in a private directory it removes at the
    end."""

    security: Security
    runtime: Path = field(init=False)
    merged: dict[str, users.User] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.merged = dict(self.security.check())  # a missing file fails before anything exists
        self.runtime = Path(tempfile.mkdtemp(prefix="darwin-up-"))

    def identity_args(self, adapter: str, role: Role) -> list[str]:
        """Make ``darwin-<adapter>`` with ``role`` and return the client options that log in
        as it."""
        name = f"{users.RESERVED_PREFIX}{adapter}"
        out: list[str] = []
        if self.security.tls:
            out += ["--ca", str(ca_paths(self.security.certs_dir).cert)]
        if self.security.mtls:
            # Issuing a certificate needs the 'security' extra (cryptography); nothing else here.
            from robot_daemon.security import certs

            paths = client_paths(self.runtime, name)
            certs.issue(self.security.certs_dir, paths, name, [], server=False)
            self.merged[name] = users.User(name, role, None)
            return [*out, "--cert", str(paths.cert), "--key", str(paths.key)]
        password = secrets.token_urlsafe(24)
        pw_file = self.runtime / f"{name}.pw"
        write_private(pw_file, password.encode())
        self.merged[name] = users.User(name, role, password)
        return [*out, "--user", name, "--password-file", str(pw_file)]

    def users_file(self) -> Path:
        """The people's identities plus the adapters', for the daemon's ``--auth``."""
        path = self.runtime / "users.toml"
        users.save(path, self.merged)
        return path

    def close(self) -> None:
        shutil.rmtree(self.runtime, ignore_errors=True)
