"""Who a client is, the same for every client (:class:`Credentials`), first found wins per item:
``--user`` / ``--password-file`` / ``--cert`` / ``--key`` / ``--ca`` (or ``Robot(user=…,
password=…)``), then ``DARWIN_USER`` / ``DARWIN_PASSWORD`` / ``DARWIN_PASSWORD_FILE`` /
``DARWIN_CERT`` / ``DARWIN_KEY`` / ``DARWIN_CA``, then the user's client file
(``$DARWIN_CLIENT_CONFIG``, else ``$XDG_CONFIG_HOME/darwin/client.toml``, else
``~/.config/darwin/client.toml``) with keys ``user``, ``password_file`` (or ``password``),
``cert``, ``key``, ``ca``. A user/password logs in (Zenoh ``transport/auth/usrpwd``); a
certificate and key make a TLS client certificate (mutual TLS, the common name is the user);
a CA alone lets a ``tls/`` endpoint check the robot's certificate.

The Zenoh session that carries them is :mod:`schemas.session`.
"""

from __future__ import annotations

import argparse
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from schemas.extras import require

ENV_USER = "DARWIN_USER"
ENV_PASSWORD = "DARWIN_PASSWORD"
ENV_PASSWORD_FILE = "DARWIN_PASSWORD_FILE"
ENV_CERT = "DARWIN_CERT"
ENV_KEY = "DARWIN_KEY"
ENV_CA = "DARWIN_CA"
ENV_CLIENT_CONFIG = "DARWIN_CLIENT_CONFIG"
LOGIN_ENV = (ENV_USER, ENV_PASSWORD, ENV_PASSWORD_FILE, ENV_CERT, ENV_KEY, ENV_CA)


def login_free_env(environ: Mapping[str, str]) -> dict[str, str]:
    """``environ`` for a child program whose login is all in its arguments: no login
    variables, and no client file (``/dev/null`` is not a file, so none is read)."""
    env = {k: v for k, v in environ.items() if k not in LOGIN_ENV}
    env[ENV_CLIENT_CONFIG] = os.devnull
    return env


@dataclass(frozen=True)
class Credentials:
    """Who a client is: a user/password login and/or a TLS client certificate."""

    user: str | None = None
    password: str | None = field(default=None, repr=False)
    cert: str | None = None
    key: str | None = None
    ca: str | None = None

    def __post_init__(self) -> None:
        if self.password is not None and not self.user:
            raise ValueError("a password needs a user name: pass --user (or DARWIN_USER)")
        if bool(self.cert) != bool(self.key):
            raise ValueError("a client certificate needs both --cert and --key")

    @property
    def identity(self) -> str | None:
        """The name access control knows this client by (user, else the certificate's CN)."""
        if self.user:
            return self.user
        if self.cert:
            x509 = require("cryptography.x509", "reading a client certificate's name")
            cert = x509.load_pem_x509_certificate(Path(self.cert).read_bytes())
            cn = x509.oid.NameOID.COMMON_NAME
            return str(cert.subject.get_attributes_for_oid(cn)[0].value)
        return None

    def apply(self, conf: zenoh.Config) -> None:
        if self.user and self.password is not None:
            conf.insert_json5("transport/auth/usrpwd/user", json.dumps(self.user))
            conf.insert_json5("transport/auth/usrpwd/password", json.dumps(self.password))
        if self.ca:
            conf.insert_json5("transport/link/tls/root_ca_certificate", json.dumps(self.ca))
        if self.cert and self.key:
            # Zenoh sends the client certificate only with mTLS on at the connecting side too.
            conf.insert_json5("transport/link/tls/enable_mtls", "true")
            conf.insert_json5("transport/link/tls/connect_certificate", json.dumps(self.cert))
            conf.insert_json5("transport/link/tls/connect_private_key", json.dumps(self.key))


def login_hint(
    creds: Credentials | None, options: str = "--user/--password-file or --cert/--key"
) -> str:
    """What to check when a session to ``creds``' endpoint does not open: the login it used
    (an endpoint with logins refuses a wrong one, or none, when the link opens)."""
    try:
        who = creds.identity if creds is not None else None
    except (OSError, ValueError, ImportError):  # a hint never fails (no 'security' extra)
        who = None
    if who:
        return (f" as {who}: check the user, password or certificate (a robot with --auth or "
                "--secure refuses a wrong one at connection)")
    return (f"; if it requires a login (--auth or --secure), pass {options} "
            "(docs/security.md)")


def client_config_path() -> Path:
    explicit = os.environ.get(ENV_CLIENT_CONFIG)
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "darwin" / "client.toml"


def _read_secret(path: str, what: str) -> str:
    try:
        text = Path(path).expanduser().read_text()
    except OSError as exc:
        raise ValueError(f"cannot read the {what} {path}: {exc.strerror or exc}") from None
    secret = text.strip("\r\n")
    if not secret or "\n" in secret:
        raise ValueError(f"the {what} {path} must hold the password alone, on one line")
    return secret


def credentials(
    user: str | None = None,
    password: str | None = None,
    password_file: str | None = None,
    cert: str | None = None,
    key: str | None = None,
    ca: str | None = None,
    fallback: bool = True,
) -> Credentials:
    """Credentials from explicit values, else (``fallback``) the environment, else the client
    file."""
    env = os.environ if fallback else {}
    file_conf: dict[str, Any] = {}
    path = client_config_path()
    if fallback and path.is_file():
        import tomllib  # here: most programs start without a client file

        try:
            file_conf = tomllib.loads(path.read_text())
        except (OSError, ValueError) as exc:  # ValueError: not TOML, or not UTF-8
            raise ValueError(f"cannot read the client file {path}: {exc}") from None

    def pick(explicit: str | None, env_name: str, file_key: str) -> str | None:
        value = explicit or env.get(env_name) or file_conf.get(file_key)
        return str(value) if value else None

    user = pick(user, ENV_USER, "user")
    if password is None:
        password_file = pick(password_file, ENV_PASSWORD_FILE, "password_file")
        if password_file:
            password = _read_secret(password_file, "password file")
        else:
            password = env.get(ENV_PASSWORD) or file_conf.get("password")
    if user and password is None:
        raise ValueError(
            f"user {user!r} has no password: pass --password-file FILE (or {ENV_PASSWORD}, or "
            f"password_file in {path})"
        )
    return Credentials(
        user, password, pick(cert, ENV_CERT, "cert"), pick(key, ENV_KEY, "key"),
        pick(ca, ENV_CA, "ca"),
    )


def credentials_from_args(args: argparse.Namespace) -> Credentials:
    """The credentials of a program with :func:`add_target_arguments`."""
    return credentials(
        user=getattr(args, "user", None),
        password_file=getattr(args, "password_file", None),
        cert=getattr(args, "cert", None),
        key=getattr(args, "key", None),
        ca=getattr(args, "ca", None),
    )


def credential_args(args: argparse.Namespace) -> list[str]:
    """The credential options given to this program, for a child program (files absolute)."""
    out: list[str] = []
    for opt in ("user", "password_file", "cert", "key", "ca"):
        value = getattr(args, opt, None)
        if value:
            if opt != "user":
                value = str(Path(value).expanduser().resolve())
            out += [f"--{opt.replace('_', '-')}", value]
    return out


def credential_env(creds: Credentials, secrets_dir: Path | None = None) -> dict[str, str]:
    """Environment variables that make a child program log in as ``creds`` (the password as
    a 0600 file in ``secrets_dir`` when given, never in the environment itself)."""
    env: dict[str, str] = {}
    if creds.user:
        env[ENV_USER] = creds.user
    if creds.password is not None and secrets_dir is not None:
        fd = os.open(secrets_dir / "password", os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(creds.password)
        env[ENV_PASSWORD_FILE] = str(secrets_dir / "password")
    for name, value in ((ENV_CERT, creds.cert), (ENV_KEY, creds.key), (ENV_CA, creds.ca)):
        if value:
            env[name] = str(Path(value).resolve())
    return env


def add_credential_arguments(parser: argparse.ArgumentParser) -> None:
    """``--user``/``--password-file``/``--cert``/``--key``/``--ca``, for every client."""
    group = parser.add_argument_group("credentials (see docs/security.md)")
    group.add_argument("--user", help=f"user name to log in as (default: ${ENV_USER})")
    group.add_argument(
        "--password-file",
        metavar="FILE",
        help=f"file holding the password (default: ${ENV_PASSWORD_FILE} or ${ENV_PASSWORD})",
    )
    group.add_argument("--cert", help=f"TLS client certificate, CN = user (default: ${ENV_CERT})")
    group.add_argument("--key", help=f"its private key (default: ${ENV_KEY})")
    group.add_argument("--ca", help=f"CA certificate that signed the robot's (default: ${ENV_CA})")
