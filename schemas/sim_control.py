"""The client of the emulator's control interface (``Keys(robot).sim_control``).

``SimControl(session, robot).call("faults", drop=0.1)`` sends ``{"v", "op": name, …fields}``
and returns the op's result; the emulator serves the ops (``robot_daemon.emulator``). Here, with
the other wire definitions, so clients (the TUI, the learning stack) reach a running emulator
without importing it.
"""

from __future__ import annotations

from typing import Any

import zenoh

from schemas.errors import ErrorCode, UnavailableError
from schemas.keys import Keys
from schemas.query import ask, request_payload
from schemas.roles import SIM_CONTROL_ROLE, Role, discover_role, require

__all__ = ["SimControl"]


class SimControl:
    """Client side: ``SimControl(session, "op1").call("faults", drop=0.1)``.

    Behind access control only :data:`~schemas.roles.SIM_CONTROL_ROLE` reaches the emulator,
    and a denied query gets no reply at all: so, like ``Robot.command``, a call first checks
    the session's role (``role``, else learnt from the daemon's role keys) and raises
    ``ForbiddenError`` naming the role that may, instead of "no emulator answers"."""

    def __init__(
        self,
        session: zenoh.Session,
        robot: str,
        timeout: float = 5.0,
        role: Role | str | None = None,
        user: str = "",
    ) -> None:
        self.session = session
        self.keys = Keys(robot)
        self.key = self.keys.sim_control
        self.timeout = timeout
        self.role: Role | str | None = role
        self.user = user

    def call(self, op: str, **fields: Any) -> dict[str, Any]:
        if self.role is None:
            # None (no daemon answers: a bare `darwin sim`) is asked again next time.
            self.role = discover_role(self.session, self.keys, min(self.timeout, 2.0))
        require(self.role, SIM_CONTROL_ROLE, f"the emulator's control ({op})", self.user, op)

        def unreachable() -> Exception:
            return UnavailableError(
                ErrorCode.UNAVAILABLE,
                f"no emulator answers on {self.key}; is `darwin sim --control-listen` running?",
                verb=op,
            )

        payload = request_payload(op=op, **fields)
        return ask(self.session, self.key, payload, self.timeout, verb=op, unreachable=unreachable)
