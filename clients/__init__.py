"""Clients of the robot's key space: the Robot API (notebooks, scripts), the TUI, recording.

``Robot`` and ``Commander`` are imported on first use, so that importing a module of this
package (``clients.commands``, read by every ``darwin`` command) costs nothing more."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from clients.commander import Commander
    from clients.robot import Robot

__all__ = ["Commander", "Robot"]


def __getattr__(name: str) -> Any:
    if name == "Robot":
        from clients.robot import Robot

        return Robot
    if name == "Commander":
        from clients.commander import Commander

        return Commander
    raise AttributeError(f"module 'clients' has no attribute {name!r}")
