"""The body (:mod:`schemas.body`) of the shipped robot config: the one place the body
description meets the config files (``schemas`` imports nothing from ``config``)."""

from __future__ import annotations

from config.loader import load_robot
from schemas.body import Body, build_body, limits_from_config


def default_body() -> Body:
    """The body for the shipped robot config."""
    robot = load_robot()
    return build_body(limits_from_config(robot), robot.max_speed)
