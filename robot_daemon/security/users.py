"""The identities file: who may reach the robot, with which role and which secret.

TOML, one table per user (``darwin users`` writes it; it is created 0600 and rewritten whole)::

    [users.alice]
    role = "operator"
    password = "…"      # absent for a certificate-only identity

Why the password is stored as it is typed: Zenoh's user/password authentication
(``transport/auth/usrpwd/dictionary_file``) compares against a plaintext ``user:password``
dictionary, so a hash here could not be checked by Zenoh. The file is therefore a secret like a
private key: owner-only permissions (refused at start if group or others can read it), and the
dictionary Zenoh reads is generated from it at start, 0600, in a private directory that goes
when the program stops (:func:`write_dictionary`).
"""

from __future__ import annotations

import json
import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path

from robot_daemon.security.paths import write_private
from schemas.errors import ConfigError
from schemas.roles import Role, parse_role

# Letters first; no ':' (the dictionary's separator) and nothing a shell or a CN would mangle.
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_.-]{0,63}$")
RESERVED_PREFIX = "darwin-"  # identities `darwin up` makes for its own children


def default_users_file() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "darwin" / "users.toml"


@dataclass(frozen=True)
class User:
    """One login of the users file: its name, role and password (None: certificate only)."""

    name: str
    role: Role
    password: str | None  # None: certificate-only


def check_name(name: str) -> str:
    if not _NAME.match(name):
        raise ValueError(
            f"user name {name!r} is not valid: start with a letter, then up to 63 letters, "
            "digits, '_', '.' or '-'"
        )
    if name.startswith(RESERVED_PREFIX):
        raise ValueError(f"user name {name!r} is reserved: names starting {RESERVED_PREFIX!r} are "
                         "the ones `darwin up` makes for its own programs")
    return name


def check_password(password: str) -> str:
    if len(password) < 8:
        raise ValueError("the password is shorter than 8 characters: choose a longer one")
    if password != password.strip() or any(c in password for c in "\r\n"):
        raise ValueError("the password must be one line without leading or trailing spaces")
    return password


def read_password_file(path: Path) -> str:
    try:
        text = path.read_text()
    except OSError as exc:
        raise ValueError(f"cannot read the password file {path}: {exc.strerror or exc}") from None
    return check_password(text.rstrip("\r\n"))


def load(path: Path, must_exist: bool = True) -> dict[str, User]:
    """The identities in ``path`` (empty when it does not exist and ``must_exist`` is False)."""
    if not path.exists():
        if must_exist:
            raise ConfigError(
                f"no identities file at {path}: create it with `darwin users add NAME --role "
                f"operator --password-file FILE --users {path}`"
            )
        return {}
    mode = stat.S_IMODE(path.stat().st_mode)
    if mode & 0o077:
        raise ConfigError(
            f"{path} holds passwords but others can read it (mode {mode:o}): run chmod 600 {path}"
        )
    import tomllib  # here: a robot without --auth starts without the parser

    try:
        data = tomllib.loads(path.read_text())
    except (OSError, ValueError) as exc:  # ValueError: not TOML, or not UTF-8
        raise ConfigError(f"cannot read the identities file {path}: {exc}") from None
    out: dict[str, User] = {}
    for name, entry in dict(data.get("users", {})).items():
        try:
            role = parse_role(str(entry.get("role", "")))
            password = entry.get("password")
            out[name] = User(name, role, None if password is None else str(password))
        except (ValueError, AttributeError) as exc:
            raise ConfigError(f"{path}: user {name!r}: {exc}") from None
    return out


def save(path: Path, users: dict[str, User]) -> None:
    lines = ["# darwin identities (`darwin users`): roles and secrets. Keep this file 0600.", ""]
    for user in sorted(users.values(), key=lambda u: u.name):
        lines.append(f"[users.{json.dumps(user.name)}]")
        lines.append(f"role = {json.dumps(str(user.role))}")
        if user.password is not None:
            lines.append(f"password = {json.dumps(user.password)}")
        lines.append("")
    write_private(path, "\n".join(lines).encode())


def add(path: Path, name: str, role: str, password: str | None) -> User:
    users = load(path, must_exist=False)
    user = User(check_name(name), parse_role(role), password)
    users[name] = user
    save(path, users)
    return user


def remove(path: Path, name: str) -> None:
    users = load(path)
    if name not in users:
        raise ValueError(f"no user {name!r} in {path}; `darwin users list` shows who is there")
    del users[name]
    save(path, users)


def write_dictionary(users: dict[str, User], path: Path) -> Path:
    """The ``user:password`` dictionary Zenoh reads, written 0600 (certificate-only users have
    no line). Zenoh refuses an empty dictionary, hence the placeholder of a random user."""
    lines = [f"{u.name}:{u.password}" for u in users.values() if u.password is not None]
    if not lines:
        lines = [f"{RESERVED_PREFIX}nobody:{os.urandom(16).hex()}"]
    write_private(path, ("\n".join(lines) + "\n").encode())
    return path
