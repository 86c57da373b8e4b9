"""The Zenoh key space, defined once (see docs in architecture.md).

Every key carries the robot name, so a fleet shares one space and ``darwin/*/joints`` watches
every robot.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from schemas.commands import SPEC

ROOT = "darwin"
DEFAULT_ROBOT = "op1"

# Verbs the arbiter serves under ``…/cmd/<verb>``, and those that never need the control lease
# (they never move the robot, or stop it): both from the one spec, ``schemas.commands.SPEC``.
VERBS: tuple[str, ...] = tuple(SPEC)
LEASE_FREE_VERBS: frozenset[str] = frozenset(v.name for v in SPEC.values() if not v.lease)

# The policy stream's keys under ``…/policy/`` (schemas/policy.py).
POLICY_TOPICS: tuple[str, ...] = ("obs", "action", "applied", "status", "dry_run")

# rmw_zenoh's key space (``clients/rmw/graph.py``), beside ours on the same routers: liveliness
# tokens under ``@ros2_lv/<domain>/…``, data and services under ``<domain>/…``.
ROS_LIVELINESS = "@ros2_lv"
ROS_DOMAINS = range(233)  # ROS domain ids 0..232


def ros_key_space() -> list[str]:
    """Key expressions covering the whole ROS 2 key space (access control's ROS rules)."""
    return [f"{ROS_LIVELINESS}/**", *(f"{d}/**" for d in ROS_DOMAINS)]


_ROBOT_NAME = re.compile(r"^[A-Za-z0-9_-]{1,64}$")


def check_robot_name(name: str) -> str:
    """Return ``name`` if it is usable inside a key expression, else raise ``ValueError``."""
    if not _ROBOT_NAME.match(name):
        raise ValueError(f"robot name {name!r} is not valid: use 1-64 letters, digits, '_' or '-'")
    return name


@dataclass(frozen=True)
class Keys:
    """Key expressions of one robot (or, with ``robot='*'``, of every robot)."""

    robot: str = DEFAULT_ROBOT

    def __post_init__(self) -> None:
        if self.robot != "*":
            check_robot_name(self.robot)

    @property
    def prefix(self) -> str:
        return f"{ROOT}/{self.robot}"

    @property
    def joints(self) -> str:
        return f"{self.prefix}/joints"

    @property
    def imu(self) -> str:
        return f"{self.prefix}/imu"

    @property
    def camera_jpeg(self) -> str:
        return f"{self.prefix}/camera/jpeg"

    @property
    def status(self) -> str:
        return f"{self.prefix}/status"

    @property
    def events(self) -> str:
        return f"{self.prefix}/events"

    @property
    def vision_ball(self) -> str:
        return f"{self.prefix}/vision/ball"

    @property
    def sim_world(self) -> str:
        return f"{self.prefix}/sim/world"

    @property
    def sim_control(self) -> str:
        """Queryable of the simulator's world/fault control interface."""
        return f"{self.prefix}/sim/control"

    @property
    def replay_control(self) -> str:
        """Queryable of ``darwin replay`` (pause, resume, seek)."""
        return f"{self.prefix}/replay/control"

    @property
    def record_control(self) -> str:
        """Queryable of ``darwin record --lerobot`` (end the episode, status)."""
        return f"{self.prefix}/record/control"

    def policy(self, what: str) -> str:
        """The policy stream (schemas/policy.py): ``obs``, ``action``, ``applied``, ``status``."""
        if what not in POLICY_TOPICS:
            raise ValueError(f"unknown policy topic {what!r}; known: {', '.join(POLICY_TOPICS)}")
        return f"{self.prefix}/policy/{what}"

    @property
    def alive(self) -> str:
        return f"{self.prefix}/alive"

    def alive_version(self, protocol: str, version: str) -> str:
        """A second liveliness token beside ``alive``, naming the daemon's protocol and package
        version (``…/alive/protocol/1.1/0.1.0``): who lists tokens sees them without a status."""
        safe = "".join(c if c.isalnum() or c in "._+-" else "_" for c in version) or "unknown"
        return f"{self.prefix}/alive/protocol/{protocol}/{safe}"

    def cmd(self, verb: str) -> str:
        if verb not in VERBS:
            raise ValueError(f"unknown command verb {verb!r}; known verbs: {', '.join(VERBS)}")
        return f"{self.prefix}/cmd/{verb}"

    def admin(self, verb: str) -> str:
        """Where the admin-only operations of ``verb`` go (``schemas.roles.ADMIN_OPS``): a key
        of their own, so that access control can give it to admins alone."""
        if verb not in VERBS:
            raise ValueError(f"unknown command verb {verb!r}; known verbs: {', '.join(VERBS)}")
        return f"{self.prefix}/admin/{verb}"

    def read(self, verb: str) -> str:
        """Where the read-only operations of a verb whose other operations change the robot
        go (``schemas.roles.READ_OPS``, e.g. ``walk_params`` without ``set``): a key of their
        own, so that access control can give observers the read and operators the write."""
        if verb not in VERBS:
            raise ValueError(f"unknown command verb {verb!r}; known verbs: {', '.join(VERBS)}")
        return f"{self.prefix}/read/{verb}"

    def role(self, role: str) -> str:
        """A queryable the daemon serves per role; access control lets a caller reach only
        its own roles' keys, so the ones that answer tell a client what it may do."""
        return f"{self.prefix}/role/{role}"

    def client(self, client_id: str) -> str:
        return f"{self.prefix}/clients/{client_id}"

    @property
    def clients_all(self) -> str:
        return f"{self.prefix}/clients/*"

    # Topics a recorder takes by default, by short name.
    def topics(self) -> dict[str, str]:
        return {
            "joints": self.joints,
            "imu": self.imu,
            "status": self.status,
            "events": self.events,
            "camera": self.camera_jpeg,
            "vision": self.vision_ball,
            "world": self.sim_world,
        }


def every_robot() -> Keys:
    """Key expressions matching every robot (``darwin/*/…``): discovery, fleet recording."""
    return Keys("*")


def verb_of(key: str) -> str:
    """The verb at the end of a ``…/cmd/<verb>`` key."""
    return key.rsplit("/", 1)[-1]


def robot_of(key: str) -> str:
    """The robot name in any ``darwin/<robot>/…`` key."""
    parts = key.split("/")
    if len(parts) < 2 or parts[0] != ROOT:
        raise ValueError(f"{key!r} is not a darwin key")
    return parts[1]
