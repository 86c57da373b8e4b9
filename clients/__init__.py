"""Clients of the robot's key space: the Robot API (notebooks, scripts), the TUI, recording."""

from clients.robot import Commander, Robot

__all__ = ["Commander", "Robot"]
