"""A fleet in the TUI: the live robots at the app's endpoint (for the connect screen's list and
F3, the next of them). Functions of the link and the names: the app's F3 action calls them."""

from __future__ import annotations

from clients.fleet import RobotRecord, discover, discover_at
from clients.tui.link import Link

FIND_TIMEOUT_S = 1.0  # how long the robot list waits for each robot's status


def find_robots(link: Link, endpoint: str) -> list[RobotRecord]:
    """Live robots at ``endpoint`` (call it in a worker thread), through the link's session
    when it goes there (a router's: the fleet), else a session of its own."""
    robot = link.robot
    if robot is not None and robot.target.endpoint == endpoint:
        return discover(robot.session, timeout=FIND_TIMEOUT_S)
    return discover_at(endpoint, timeout=FIND_TIMEOUT_S, creds=link.credentials)


def next_robot(names: list[str], current: str) -> str | None:
    """The live robot after ``current`` by name, wrapping round; None when it is alone."""
    others = [n for n in names if n != current]
    if not others:
        return None
    later = [n for n in others if n > current]
    return (later or others)[0]
