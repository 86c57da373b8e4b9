"""Test-side transform helpers: a quaternion as a matrix, and a tree of edges composed.

Written independently of the code under test (``schemas.kinematics.quaternion``), so the tests
that use them check it rather than repeat it."""

from __future__ import annotations

import numpy as np


def quat_matrix(x: float, y: float, z: float, w: float) -> np.ndarray:
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def compose(tree: list[tuple[str, str, np.ndarray]], root: str = "base_link") -> dict:
    """Every frame's pose in ``root`` from (parent, child, pose) edges."""
    edges = {child: (parent, pose) for parent, child, pose in tree}
    poses: dict[str, np.ndarray] = {root: np.eye(4)}

    def pose_of(frame: str) -> np.ndarray:
        if frame not in poses:
            parent, local = edges[frame]
            poses[frame] = pose_of(parent) @ local
        return poses[frame]

    return {frame: pose_of(frame) for frame in edges if frame != root}


def tf_poses(transforms: list, root: str = "base_link") -> dict:
    """Every frame's pose in ``root`` from Foxglove ``FrameTransform`` messages (``field`` and
    what hangs from it left out)."""
    edges = [
        (
            t.parent_frame_id,
            t.child_frame_id,
            _pose(t.rotation, t.translation),
        )
        for t in transforms
        if t.parent_frame_id != "field"
    ]
    return compose(edges, root)


def _pose(q, v) -> np.ndarray:  # type: ignore[no-untyped-def]
    pose = np.eye(4)
    pose[:3, :3] = quat_matrix(q.x, q.y, q.z, q.w)
    pose[:3, 3] = (v.x, v.y, v.z)
    return pose
