"""Where the Foxglove server gets the robot's body: the project's one body description."""

from __future__ import annotations

import logging

from clients.robot import Robot
from config.loader import load_robot
from schemas.body import Body, build_body, limits_from_config
from schemas.errors import DarwinError
from schemas.urdf import body_from_config_reply

log = logging.getLogger(__name__)


def robot_body(robot: Robot) -> Body:
    """The body of the robot this server shows, with the joint limits its daemon reports; a
    replay has no daemon to ask, so then the limits of this machine's config."""
    try:
        return body_from_config_reply(robot.config())
    except DarwinError as exc:
        log.info("no config reply (%s): the URDF uses this machine's joint limits", exc)
        local = load_robot()
        return build_body(limits_from_config(local), local.max_speed)
