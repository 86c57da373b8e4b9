"""Which motion modules the daemon runs, in tick order. The one place to add a module."""

from __future__ import annotations

from typing import Any

from config.loader import RobotConfig
from robot_daemon.motion.direct import DirectModule
from robot_daemon.motion.manager import MotionManager


def build_manager(robot: RobotConfig, settings: dict[str, Any]) -> MotionManager:
    """A manager with every module attached. ``settings`` is the merged config (all sections).

    Order matters: modules later in the list see the same frame but run after earlier ones
    (action, head, walking, as the framework does; direct joint control last)."""
    manager = MotionManager(robot)
    manager.add(DirectModule(default_speed=float(robot.max_speed) / 2))
    return manager
