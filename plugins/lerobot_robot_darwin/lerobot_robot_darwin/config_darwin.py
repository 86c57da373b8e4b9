from __future__ import annotations

from dataclasses import dataclass

from lerobot.robots.config import RobotConfig


@RobotConfig.register_subclass("darwin")
@dataclass
class DarwinConfig(RobotConfig):
    endpoint: str | None = None  # the robot's Zenoh endpoint (else DARWIN_ENDPOINT)
    robot: str | None = None  # the robot's name (else DARWIN_ROBOT)
    rate_hz: float = 50.0  # the policy stream's rate (25..125)
