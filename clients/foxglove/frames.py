"""The transform tree Foxglove's 3D panel draws, from the project's forward kinematics.

Every link pose comes from :mod:`schemas.kinematics` (nothing here re-derives a chain): each
frame is published as a child of ``base_link`` with its pose in the body frame, so the tree is
exact whatever the URDF's own joint structure. ``field → base_link`` places the body on the
ground (the lower sole touches z = 0) at the simulated world pose when there is one.

LEAD: the frame names below must be the URDF's link names (schemas/body.py) for Foxglove's URDF
layer to move the meshes; keep them in this one mapping.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from schemas import kinematics as K

BASE = "base_link"
FIELD = "field"
BALL = "ball"
LEG_FRAMES = ("hip", "knee", "ankle", "foot")  # the four poses of kinematics.leg_chain
ARM_FRAMES = ("shoulder", "elbow", "hand")  # the three points of kinematics.arm_chain


def positions_by_id(ids: Sequence[int], position: Sequence[float]) -> dict[int, float]:
    """``{joint id: rad}`` from a Joints message's columns."""
    return {int(i): float(p) for i, p in zip(ids, position, strict=False)}


def link_poses(positions: Mapping[int, float]) -> dict[str, np.ndarray]:
    """Every link's pose (4×4, body frame) for the given servo angles."""
    poses: dict[str, np.ndarray] = {}
    head = K.head_pose(positions)
    poses["head"] = head
    poses["camera"] = K.camera_pose(positions)
    for side in K.SIDES:
        p = side[0]
        base = K.transform(translation=K.hip_point(side))
        chain = K.leg_chain(K.servo_to_leg_angles(positions, side))
        for name, pose in zip(LEG_FRAMES, chain, strict=True):
            poses[f"{p}_{name}"] = base @ pose
        # The arms feed only the drawing: the kinematics gives points, so the frames are
        # translations in the body's orientation.
        for name, point in zip(ARM_FRAMES, K.arm_chain(positions, side), strict=True):
            poses[f"{p}_{name}"] = K.transform(translation=point)
    return poses


def standing_height(poses: Mapping[str, np.ndarray]) -> float:
    """How high the body origin is above the ground: the lower sole on z = 0."""
    return -min(float(poses["r_foot"][2, 3]), float(poses["l_foot"][2, 3]))


def quaternion(r: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation matrix (Shepperd's method, numerically safe)."""
    m = r[:3, :3]
    tr = float(m[0, 0] + m[1, 1] + m[2, 2])
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        return (
            (m[2, 1] - m[1, 2]) / s,
            (m[0, 2] - m[2, 0]) / s,
            (m[1, 0] - m[0, 1]) / s,
            0.25 * s,
        )
    i = int(np.argmax([m[0, 0], m[1, 1], m[2, 2]]))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k]) * 2
    q = [0.0, 0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (m[j, i] + m[i, j]) / s
    q[k] = (m[k, i] + m[i, k]) / s
    q[3] = (m[k, j] - m[j, k]) / s
    return q[0], q[1], q[2], q[3]


def body_transforms(positions: Mapping[int, float]) -> list[tuple[str, str, np.ndarray]]:
    """``(parent, child, pose)`` for every link plus ``field → base_link`` at the origin
    (:func:`world_transforms` replaces that one when a world pose is known)."""
    poses = link_poses(positions)
    out = [(BASE, name, pose) for name, pose in poses.items()]
    out.append((FIELD, BASE, K.transform(translation=(0.0, 0.0, standing_height(poses)))))
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
