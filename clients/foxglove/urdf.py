"""Where the Foxglove server gets the robot's URDF: the project's one body description."""

from __future__ import annotations

import logging

from clients.robot import Robot
from config.loader import load_robot
from schemas.body import build_body, limits_from_config
from schemas.errors import DarwinError
from schemas.urdf import to_urdf, urdf_from_config_reply

log = logging.getLogger(__name__)


def robot_description(robot: Robot) -> str:
    """The URDF of the robot this server shows, with the joint limits its daemon reports; a
    replay has no daemon to ask, so then the limits of this machine's config."""
    try:
        return urdf_from_config_reply(robot.config())
    except DarwinError as exc:
        log.info("no config reply (%s): the URDF uses this machine's joint limits", exc)
        local = load_robot()
        return to_urdf(build_body(limits_from_config(local), local.max_speed))
