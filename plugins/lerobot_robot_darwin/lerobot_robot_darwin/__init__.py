"""The DARwIn-OP as a LeRobot ``Robot``: a thin client of the darwin-zenoh key space.

LeRobot's contract (``lerobot.robots.robot.Robot``): ``observation_features`` and
``action_features`` (name → type or shape), ``connect``/``disconnect``, ``get_observation()``
and ``send_action(action)`` returning the action actually sent. Here the observation is the
policy contract's (schemas/policy.py): one float per named element of the observation vector;
the action is one offset per joint (``<joint>.pos``, × 0.3 rad from the default pose), and what
``send_action`` returns is the daemon's ``PolicyApplied`` answer after clipping.
"""

from lerobot_robot_darwin.config_darwin import DarwinConfig
from lerobot_robot_darwin.darwin import Darwin

__all__ = ["Darwin", "DarwinConfig"]
