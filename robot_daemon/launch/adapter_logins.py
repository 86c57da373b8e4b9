"""Who the programs ``darwin up`` starts next to the robot log in as: the adapters the packages
declare (:mod:`schemas.registry`) and the UI of ``--tui``. Never as the robot: the robot's
identity (under ``--router``) may do everything, an adapter gets the least role it needs
(``[adapters.<name>]`` in ``config/adapters.toml``, ``--adapter-role``).

- an identity configured for it (``user``/``password_file``/``cert``/``key``/``ca`` in
  ``[adapters.<name>]``) always wins;
- under ``--router`` the router's identities decide who is who, so an adapter of a robot that
  logs in there needs one configured: without it it is not started (:attr:`Login.refused`);
  the UI then logs in as the person (their ``DARWIN_USER`` or client file), never as the robot;
- with ``--auth``/``--secure`` (the daemon enforces) it logs in as ``darwin-<name>``, made at
  start with its role (:class:`~robot_daemon.security.internal.Internal`); the UI as the person
  when ``darwin up`` got their ``--user``/``--cert`` (or the environment has them);
- otherwise nobody logs in.
"""

from __future__ import annotations

import argparse
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from config.loader import refuse_unknown
from schemas import registry
from schemas.errors import ConfigError
from schemas.roles import Role, parse_role
from schemas.session import (
    credential_args,
    credentials,
    credentials_from_args,
    login_free_env,
)

if TYPE_CHECKING:
    from robot_daemon.security.internal import Internal

_LOGIN_KEYS = ("user", "password_file", "cert", "key", "ca")


@dataclass(frozen=True)
class Login:
    """How an adapter ``darwin up`` starts logs in: its role and client options, or why it may
    not run."""

    role: Role
    args: list[str]  # the client options it logs in with
    refused: str = ""  # why it may not run (then args is empty)
    # The args are the whole login: the program runs without the DARWIN_USER… variables and
    # the client file of whoever started ``darwin up`` (else an adapter could log in as them,
    # or mix their certificate into its own login, or present a password to an open robot).
    isolated: bool = True

    def env(self) -> dict[str, str] | None:
        """The child's environment (None: this one's)."""
        return login_free_env(os.environ) if self.isolated else None


def roles(settings: dict[str, Any], overrides: list[str] | None) -> dict[str, Role]:
    """Each adapter's role: ``[adapters.<name>] role``, then ``--adapter-role ROLE`` (all)
    and ``--adapter-role NAME=ROLE`` (one), in the order given."""
    table = settings.get("adapters", {})
    out: dict[str, Role] = {}
    for name in names():
        section = table.get(name, {})
        refuse_unknown(section, ("role", *_LOGIN_KEYS), f"adapters.{name}")
        out[name] = _role(str(section.get("role", Role.OPERATOR)), f"[adapters.{name}] role")
    for item in overrides or []:
        name, sep, role = item.rpartition("=")
        if sep and name not in out:
            raise ConfigError(f"--adapter-role {item}: {name!r} is not one of "
                              f"{', '.join(out)}")
        for each in [name] if sep else list(out):
            out[each] = _role(role, f"--adapter-role {item}")
    return out


def names() -> tuple[str, ...]:
    """Every adapter's name and the UI's: their sections ``[adapters.NAME]``, their logins."""
    return tuple(adapter.name for adapter in registry.adapters())


def _role(text: str, where: str) -> Role:
    try:
        return parse_role(text, people_only=True)
    except ValueError as exc:
        raise ConfigError(f"{where}: {exc}") from None


def configured(settings: dict[str, Any], name: str) -> list[str]:
    """The login options of ``[adapters.<name>]`` (files made absolute), or none."""
    section = settings.get("adapters", {}).get(name, {})
    return credential_args(argparse.Namespace(**{k: section.get(k) for k in _LOGIN_KEYS}))


def _identity(**kwargs: Any) -> str | None:
    try:
        return credentials(**kwargs).identity
    except (ValueError, OSError) as exc:
        raise ConfigError(str(exc)) from None


def adapter_login(
    name: str, role: Role, settings: dict[str, Any], args: argparse.Namespace,
    router: str | None, internal: Internal | None,
) -> Login:
    own = configured(settings, name)
    if own:
        return Login(role, own)
    if router:
        robot = robot_identity(args)
        if robot:
            return Login(role, [], (
                f"under --router it logs in with an identity of its own, not the robot's "
                f"({robot}): add one to the router's identities (`darwin users add NAME --role "
                f"{role} --password-file F`) and set user and password_file in "
                f"[adapters.{name}] of --config"
            ))
        return Login(role, [])  # an open router: nobody logs in
    return Login(role, internal.identity_args(name, role) if internal is not None else [])


def ui_login(
    name: str, role: Role, settings: dict[str, Any], args: argparse.Namespace, router: str | None,
    internal: Internal | None,
) -> Login:
    own = configured(settings, name)
    if own:
        return Login(role, own)
    if router:
        # up's --user… are the robot's here; the UI finds the person's login itself (their
        # DARWIN_USER, their client file), which must not be the robot's.
        robot, person = robot_identity(args), _identity()
        if robot and person == robot:
            return Login(role, [], (
                f"--tui would log in as the robot ({robot}): give the UI a login of its own "
                f"(DARWIN_USER/DARWIN_PASSWORD_FILE, ~/.config/darwin/client.toml, or user and "
                f"password_file in [adapters.{name}] of --config)"
            ))
        return Login(role, [], isolated=False)
    person_args = credential_args(args)
    if person_args or internal is None:
        return Login(role, person_args)  # the person at this terminal (none: an open robot)
    if _identity():
        return Login(role, [], isolated=False)  # the person's own environment or client file
    return Login(role, internal.identity_args(name, role))


def robot_identity(args: argparse.Namespace) -> str | None:
    """Who the robot logs in to a router as (``--user``…, else the environment/client file)."""
    try:
        return credentials_from_args(args).identity
    except (ValueError, OSError) as exc:
        raise ConfigError(str(exc)) from None
