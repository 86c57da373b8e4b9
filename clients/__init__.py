"""Clients of the robot's key space: the Robot API (notebooks, scripts), the TUI, recording."""

from clients.commander import Commander
from clients.robot import Robot

__all__ = ["Commander", "Robot"]
