"""The walking parameters as Foxglove parameters ``walk/<name>``: read by anyone, written with
the lease through the arbiter's ``walk_params`` verb (which checks every range)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from foxglove.websocket import Parameter, ParameterType

from clients.foxglove.control import Commanders
from clients.robot import Robot
from schemas.errors import DarwinError

PREFIX = "walk/"


def to_parameter(name: str, value: Any) -> Parameter:
    if isinstance(value, bool | int):
        return Parameter(PREFIX + name, value=value)
    return Parameter(PREFIX + name, value=float(value), type=ParameterType.Float64)


class WalkParameters:
    def __init__(self, commanders: Commanders, robot: Robot, report: Callable[[str], None]):
        self.commanders = commanders
        self.robot = robot
        self.report = report

    def current(self) -> dict[str, Any]:
        return dict(self.robot.command("walk_params").get("params", {}))

    def get(self, names: list[str]) -> list[Parameter]:
        params = self.current()
        wanted = {n.removeprefix(PREFIX) for n in names} if names else set(params)
        unknown = sorted(n for n in wanted if n not in params)
        if unknown:
            self.report(f"unknown parameter {PREFIX}{unknown[0]}; see getParameters with no names")
        return [to_parameter(n, v) for n, v in params.items() if n in wanted]

    def set(self, client_id: int, parameters: list[Parameter]) -> list[Parameter]:
        """Apply all or nothing; the reply carries the values now in force, so a refused
        change shows its old value next to the status message naming what was wrong."""
        changes: dict[str, Any] = {}
        for p in parameters:
            if not p.name.startswith(PREFIX):
                self.report(f"unknown parameter {p.name!r}: walking parameters are {PREFIX}<name>")
                return self._reply(parameters)
            value = p.get_value()
            if value is None or isinstance(value, bytes | str | list | dict):
                self.report(f"{p.name}: a number or boolean is needed, not {value!r}")
                return self._reply(parameters)
            changes[p.name.removeprefix(PREFIX)] = value
        if changes:
            try:
                self.commanders.get(client_id).command("walk_params", set=changes)
            except DarwinError as exc:
                self.report(f"walking parameters not changed: {exc}")
        return self._reply(parameters)

    def _reply(self, parameters: list[Parameter]) -> list[Parameter]:
        params = self.current()
        names = {p.name.removeprefix(PREFIX) for p in parameters}
        return [to_parameter(n, v) for n, v in params.items() if n in names]
