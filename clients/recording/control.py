"""``ReplayControl``: the client of a running ``darwin replay`` (what the TUI uses).

>>> ctl = ReplayControl(robot)            # a Robot/Commander of the replayed robot name
>>> ctl.pause(); ctl.seek(12.5); ctl.resume(); ctl.status()["position"]
"""

from __future__ import annotations

from typing import Any

import zenoh

from clients.commander import Commander
from schemas.errors import RobotUnreachableError
from schemas.keys import Keys
from schemas.query import ask, request_payload


class ReplayControl:
    def __init__(
        self, source: Commander | zenoh.Session, robot: str | None = None, timeout: float = 2.0
    ) -> None:
        if isinstance(source, Commander):
            self._session = source.session
            self.keys = Keys(robot or source.keys.robot)
        else:
            if robot is None:
                raise ValueError("pass the replayed robot's name with a bare Zenoh session")
            self._session = source
            self.keys = Keys(robot)
        self.timeout = timeout

    def __repr__(self) -> str:
        return f"<ReplayControl {self.keys.replay_control}>"

    def _ask(self, op: str, **fields: Any) -> dict[str, Any]:
        key = self.keys.replay_control

        def unreachable() -> Exception:
            return RobotUnreachableError(
                f"nobody answers {key}: is `darwin replay … --robot {self.keys.robot}` running "
                "and connected to the same Zenoh network?"
            )

        payload = request_payload(op=op, **fields)
        return ask(self._session, key, payload, self.timeout, verb=op, unreachable=unreachable)

    def status(self) -> dict[str, Any]:
        return self._ask("status")

    def pause(self) -> dict[str, Any]:
        return self._ask("pause")

    def resume(self) -> dict[str, Any]:
        return self._ask("resume")

    def seek(self, t: float) -> dict[str, Any]:
        return self._ask("seek", t=t)

    def rate(self, rate: float) -> dict[str, Any]:
        return self._ask("rate", rate=rate)
