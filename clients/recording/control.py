"""The clients of a running ``darwin replay`` (``ReplayControl``, what the TUI uses) and of a
running ``darwin record --lerobot`` (``RecordControl``).

>>> ctl = ReplayControl(robot)            # a Robot/Commander of the replayed robot name
>>> ctl.pause(); ctl.seek(12.5); ctl.resume(); ctl.status()["position"]
>>> RecordControl(robot).episode(task="stand")   # end the episode, the next has this task
"""

from __future__ import annotations

from typing import Any

import zenoh

from clients.commander import Commander
from schemas.errors import RobotUnreachableError
from schemas.keys import Keys
from schemas.query import ask, request_payload


class _Control:
    PROGRAM = ""  # the program that answers, for the unreachable message

    def __init__(
        self, source: Commander | zenoh.Session, robot: str | None = None, timeout: float = 2.0
    ) -> None:
        if isinstance(source, Commander):
            self._session = source.session
            self.keys = Keys(robot or source.keys.robot)
        else:
            if robot is None:
                raise ValueError("pass the robot's name with a bare Zenoh session")
            self._session = source
            self.keys = Keys(robot)
        self.timeout = timeout

    @property
    def key(self) -> str:
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.key}>"

    def _ask(self, op: str, **fields: Any) -> dict[str, Any]:
        key = self.key

        def unreachable() -> Exception:
            return RobotUnreachableError(
                f"nobody answers {key}: is `{self.PROGRAM} --robot {self.keys.robot}` running "
                "and connected to the same Zenoh network?"
            )

        payload = request_payload(op=op, **fields)
        return ask(self._session, key, payload, self.timeout, verb=op, unreachable=unreachable)

    def status(self) -> dict[str, Any]:
        return self._ask("status")


class ReplayControl(_Control):
    PROGRAM = "darwin replay …"

    @property
    def key(self) -> str:
        return self.keys.replay_control

    def pause(self) -> dict[str, Any]:
        return self._ask("pause")

    def resume(self) -> dict[str, Any]:
        return self._ask("resume")

    def seek(self, t: float) -> dict[str, Any]:
        return self._ask("seek", t=t)

    def rate(self, rate: float) -> dict[str, Any]:
        return self._ask("rate", rate=rate)


class RecordControl(_Control):
    PROGRAM = "darwin record --lerobot DIR"

    def __init__(
        self, source: Commander | zenoh.Session, robot: str | None = None, timeout: float = 10.0
    ) -> None:
        # Ending an episode writes it (parquet, and the video closed) before the reply.
        super().__init__(source, robot, timeout)

    @property
    def key(self) -> str:
        return self.keys.record_control

    def episode(self, task: str | None = None) -> dict[str, Any]:
        """End the open episode (written when this returns) and start the next."""
        return self._ask("episode", **({} if task is None else {"task": task}))
