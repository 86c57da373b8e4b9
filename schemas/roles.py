"""Roles: who may do what on the key space, declared once.

The access-control generator (``robot_daemon.security.acl``), the clients' early check
(:func:`check`) and the TUI's greying all read :data:`ROLES`. Zenoh access control is the real
enforcement, on key expressions; this table is why an operation that only differs from another
by its payload (a register *write* next to a register read) has a key of its own,
``darwin/<robot>/admin/<verb>`` (:func:`command_key`): the arbiter serves the admin-only
operations there alone (``forbidden`` on ``cmd/``), so the ACL can give that key to admins only.
Likewise a read that shares its verb with a write (``walk_params`` without ``set``) has
``darwin/<robot>/read/<verb>`` (:data:`READ_OPS`), the key observers may query.

- observer: subscribe to everything, read ``config``, ``behaviours`` and the gait parameters
  (``walk_params`` without ``set``; status is published);
- operator: observer + every command verb, the lease, and replay control;
- admin: operator + register writes (EEPROM and protected registers), page library writes
  (pages put/delete/reload: files on the robot's disk) and the emulator's control interface
  (:data:`SIM_CONTROL_ROLE`).

``robot`` is not a person's role: it is the identity a daemon uses to join an authenticated
router (it publishes and serves its whole key space).
"""

from __future__ import annotations

from enum import StrEnum
from typing import Any

from schemas import qos
from schemas.commands import SPEC, op_of
from schemas.errors import ErrorCode, ForbiddenError
from schemas.keys import VERBS, Keys


class Role(StrEnum):
    OBSERVER = "observer"
    OPERATOR = "operator"
    ADMIN = "admin"
    ROBOT = "robot"


# People's roles from least to most allowed; each includes everything before it.
LADDER: tuple[Role, ...] = (Role.OBSERVER, Role.OPERATOR, Role.ADMIN)

# Verbs an observer may query (their key ``cmd/<verb>``): reads that never change anything.
READ_VERBS: frozenset[str] = frozenset(v.name for v in SPEC.values() if v.read)

# verb → the ops (``op`` field, or "write" for a registers write) that only an admin may send;
# they travel on ``admin/<verb>``.
ADMIN_OPS: dict[str, frozenset[str]] = {v.name: v.admin_ops for v in SPEC.values() if v.admin_ops}
ADMIN_VERBS: tuple[str, ...] = tuple(ADMIN_OPS)

# verb → its read-only ops that an observer may send, where the verb's other ops change the
# robot; they travel on ``read/<verb>`` (the writes stay on ``cmd/<verb>``, for operators).
READ_OPS: dict[str, frozenset[str]] = {v.name: v.read_ops for v in SPEC.values() if v.read_ops}
READ_OP_VERBS: tuple[str, ...] = tuple(READ_OPS)

# The emulator's control interface (``Keys.sim_control``: world ops, faults): admins only.
SIM_CONTROL_ROLE = Role.ADMIN


def parse_role(text: str, people_only: bool = False) -> Role:
    """The role named ``text``, or ``ValueError`` listing the roles."""
    allowed = LADDER if people_only else tuple(Role)
    try:
        role = Role(text)
    except ValueError:
        role = None
    if role is None or role not in allowed:
        raise ValueError(f"role {text!r} is not one of {', '.join(allowed)}")
    return role


def is_admin_op(verb: str, fields: dict[str, Any]) -> bool:
    return op_of(verb, fields) in ADMIN_OPS.get(verb, frozenset())


def is_read_op(verb: str, fields: dict[str, Any]) -> bool:
    return op_of(verb, fields) in READ_OPS.get(verb, frozenset())


def required_role(verb: str, fields: dict[str, Any]) -> Role:
    """The least role that may send this command."""
    if is_admin_op(verb, fields):
        return Role.ADMIN
    if verb in READ_VERBS or is_read_op(verb, fields):
        return Role.OBSERVER
    return Role.OPERATOR


def at_least(role: Role | str | None, need: Role) -> bool:
    """True when ``role`` includes ``need`` (an unknown role, ``None``, allows all: the robot
    then decides)."""
    if role is None or role == Role.ROBOT:
        return True
    return LADDER.index(Role(role)) >= LADDER.index(need)


def allows(role: Role | str | None, verb: str, fields: dict[str, Any] | None = None) -> bool:
    """True when ``role`` may send this command."""
    return at_least(role, required_role(verb, fields or {}))


def require(role: Role | str | None, need: Role, what: str, user: str = "", verb: str = "") -> None:
    """Raise :class:`ForbiddenError` naming ``need`` unless ``role`` includes it: access control
    drops a denied query without a reply, which would look like an unreachable robot."""
    if at_least(role, need):
        return
    who = f"{user} is {role}" if user else f"this identity's role is {role}"
    refused = ForbiddenError(
        ErrorCode.FORBIDDEN,
        f"{what} needs the {need} role ({who}); an admin can grant it with "
        f"`darwin users add NAME --role {need} …`",
        verb=verb or what,
    )
    refused.role = str(need)
    raise refused


def check(role: Role | str | None, verb: str, fields: dict[str, Any], user: str = "") -> None:
    """Raise :class:`ForbiddenError` naming the role that would allow the command."""
    what = verb if verb not in ADMIN_OPS else f"{verb} {op_of(verb, fields)}".strip()
    require(role, required_role(verb, fields), what, user, verb)


def command_key(keys: Keys, verb: str, fields: dict[str, Any]) -> str:
    """Where a command goes: ``admin/<verb>`` for an admin-only operation, ``read/<verb>`` for
    a read an observer may send (:data:`READ_OPS`), else ``cmd/<verb>``."""
    if is_admin_op(verb, fields):
        return keys.admin(verb)
    return keys.read(verb) if is_read_op(verb, fields) else keys.cmd(verb)


def verbs_allowed(role: Role | str | None) -> frozenset[str]:
    """The verbs ``role`` may send at all (some of their ops may still need more)."""
    return frozenset(v for v in VERBS if allows(role, v, {}))


def discover_role(session: Any, keys: Keys, timeout: float) -> Role | None:
    """The highest role whose key (``Keys.role``) answers: access control lets each caller
    reach only its own roles' keys, and drops the others at once (no reply, no wait)."""
    pending = {
        r: session.get(keys.role(r), timeout=timeout, **qos.for_key(keys.role(r)).kwargs())
        for r in LADDER
    }
    answered = {r for r, replies in pending.items() if any(x.ok is not None for x in replies)}
    return max(answered, key=LADDER.index) if answered else None
