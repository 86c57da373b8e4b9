"""The transform tree Foxglove's 3D panel draws: the URDF's own tree, from the body description.

Every transform is one joint of :mod:`schemas.body` (the description the URDF is generated
from), parent link to child link, so Foxglove's URDF layer moves each link by its own name and
the tree is the one ROS 2's ``tf`` carries. ``field → base_link`` places the body on the ground
(the lower sole touches z = 0) at the simulated world pose when there is one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from schemas import kinematics as K
from schemas.body import Body

BASE = "base_link"
FIELD = "field"
BALL = "ball"
SOLES = ("r_sole", "l_sole")


def positions_by_id(ids: Sequence[int], position: Sequence[float]) -> dict[int, float]:
    """``{joint id: rad}`` from a Joints message's columns."""
    return {int(i): float(p) for i, p in zip(ids, position, strict=False)}


def standing_height(poses: Mapping[str, np.ndarray]) -> float:
    """How high the body origin is above the ground: the lower sole on z = 0."""
    return -min(float(poses[sole][2, 3]) for sole in SOLES)


def body_transforms(
    body: Body, positions: Mapping[int, float]
) -> list[tuple[str, str, np.ndarray]]:
    """``(parent, child, pose)`` for every joint of the body, plus ``field → base_link`` at the
    origin (:func:`world_transforms` replaces that one when a world pose is known)."""
    out = [(j.parent, j.child, body.joint_transform(j, positions)) for j in body.joints]
    height = standing_height(body.link_poses(positions))
    out.append((FIELD, BASE, K.transform(translation=(0.0, 0.0, height))))
    return out


def world_transforms(
    world: Any, height: float
) -> list[tuple[str, str, np.ndarray]]:
    """``field → base_link`` and ``field → ball`` from a :class:`schemas.messages.World`."""
    robot = world.robot or {}
    out = [
        (
            FIELD,
            BASE,
            K.transform(
                K.rot_z(float(robot.get("yaw", 0.0))),
                (float(robot.get("x", 0.0)), float(robot.get("y", 0.0)), height),
            ),
        )
    ]
    if world.ball:
        out.append(
            (
                FIELD,
                BALL,
                K.transform(translation=(float(world.ball["x"]), float(world.ball["y"]), 0.0)),
            )
        )
    return out
