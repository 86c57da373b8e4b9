"""``ReplayControl``: the client of a running ``darwin replay`` (what the TUI uses).

>>> ctl = ReplayControl(robot)            # a Robot/Commander of the replayed robot name
>>> ctl.pause(); ctl.seek(12.5); ctl.resume(); ctl.status()["position"]
"""

from __future__ import annotations

from typing import Any

import msgpack
import zenoh

from clients.robot import Commander
from schemas import SCHEMA_VERSION
from schemas.errors import ErrorCode, RobotUnreachableError, command_error
from schemas.keys import Keys
from schemas.messages import decode_dict


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
        payload = msgpack.packb({"v": SCHEMA_VERSION, "op": op, **fields}, use_bin_type=True)
        key = self.keys.replay_control
        replies = list(self._session.get(key, payload=payload, timeout=self.timeout))
        if not replies:
            raise RobotUnreachableError(
                f"nobody answers {key}: is `darwin replay … --robot {self.keys.robot}` running "
                "and connected to the same Zenoh network?"
            )
        reply = replies[0]
        if reply.ok is not None:
            return decode_dict(reply.ok.payload.to_bytes()).get("applied", {})
        raw = reply.err.payload.to_bytes()
        try:
            d = decode_dict(raw)
        except Exception:
            d = {"code": ErrorCode.INTERNAL, "message": raw.decode("utf-8", "replace")}
        raise command_error(d.get("code", "internal"), d.get("message", ""), d.get("field"), op)

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
