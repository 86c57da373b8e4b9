"""Shipped configuration (TOML files in this folder) and the loader that merges user overrides."""

from config.loader import (
    JointConfig,
    RobotConfig,
    load_robot,
    load_section,
    user_config_path,
)

__all__ = ["JointConfig", "RobotConfig", "load_robot", "load_section", "user_config_path"]
