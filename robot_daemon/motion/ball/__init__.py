"""Ball play: head tracking and search, the ball follower, the kick (see ``module.py``)."""

from __future__ import annotations

from typing import Any

from robot_daemon.motion.ball.module import BallPlayModule
from robot_daemon.motion.ball.settings import BallPlaySettings


def ball_module(settings: dict[str, Any]) -> BallPlayModule:
    """The module from the merged config (its ``[ballplay]`` section)."""
    return BallPlayModule(BallPlaySettings.from_config(settings.get("ballplay", {})))
