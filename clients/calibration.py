"""Offset calibration from a client: ``robot.calibration`` (an :class:`OffsetTuner`).

    with robot.control("calibration"):
        cal = robot.calibration
        cal.reference_pose()              # ROBOTIS's offset-tuner posture: every servo centred
        cal.nudge("r_knee", +0.5)         # degrees; the daemon applies it at once
        cal.mirror("r_knee")              # l_knee gets the mirrored offset
        cal.undo()                        # back one change
        cal.save()                        # [robot.joints.<name>] offset_deg in the user config

Setting offsets is an admin operation (``offsets`` with ``op: set``, on ``admin/offsets``) and
needs the lease; reading them (``get``) is open to observers. The reference posture is the one of
ROBOTIS's offset tuner (``Linux/project/offset_tuner``: ``InitPose`` of 2047 for every ID, each
sent with the offset added): every joint at its zero, arms hanging, legs straight; a robot on a
stand, so that nothing but gravity loads the joints while each is checked against its marks.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

from config.user_file import set_joint_offsets

if TYPE_CHECKING:
    from pathlib import Path

    from clients.robot import Commander


def partner(name: str) -> str | None:
    """The joint on the other side (``r_knee`` ↔ ``l_knee``), None for the head."""
    if name.startswith("r_"):
        return "l_" + name[2:]
    if name.startswith("l_"):
        return "r_" + name[2:]
    return None


class OffsetTuner:
    """Nudge, mirror, undo, reset and save the joints' offsets on a live daemon."""

    def __init__(self, robot: Commander) -> None:
        self.robot = robot
        self.history: list[dict[str, float]] = []  # offsets before each change, newest last
        self._offsets: dict[str, float] | None = None

    @property
    def offsets(self) -> dict[str, float]:
        """The daemon's offsets (degrees by joint name), as last read or set."""
        if self._offsets is None:
            self.refresh()
        assert self._offsets is not None
        return dict(self._offsets)

    def refresh(self) -> dict[str, float]:
        self._offsets = dict(self.robot.command("offsets", op="get")["offsets"])
        return dict(self._offsets)

    def set(self, changes: dict[str, float]) -> dict[str, float]:
        """Set some joints' offsets (degrees); the previous ones can be restored by :meth:`undo`."""
        before = self.offsets
        reply = self.robot.command("offsets", op="set", offsets=dict(changes))
        self.history.append(before)
        self._offsets = dict(reply["offsets"])
        return dict(self._offsets)

    def nudge(self, joint: str, delta_deg: float) -> dict[str, float]:
        return self.set({joint: self.offsets[joint] + delta_deg})

    def mirror(self, joint: str) -> dict[str, float]:
        """Give ``joint``'s partner on the other side the mirrored offset. The DARwIn-OP's left
        and right servos are mounted as mirror images (ROBOTIS's pages hold 2048 ± x for a
        pair in a symmetric pose), so the same correction is the opposite servo turn."""
        other = partner(joint)
        if other is None:
            raise ValueError(f"{joint} has no partner on the other side to mirror to")
        return self.set({other: -self.offsets[joint]})

    def undo(self) -> dict[str, float]:
        if not self.history:
            raise ValueError("nothing to undo")
        before = self.history.pop()
        now = self.offsets
        changed = {k: v for k, v in before.items() if now.get(k) != v}
        if changed:
            reply = self.robot.command("offsets", op="set", offsets=changed)
            self._offsets = dict(reply["offsets"])
        return self.offsets

    def reset(self, joints: list[str] | None = None) -> dict[str, float]:
        """Offsets back to 0 (every joint, or ``joints``); undoable."""
        names = joints or list(self.offsets)
        return self.set(dict.fromkeys(names, 0.0))

    def reference_pose(self, duration: float = 2.0) -> dict[str, Any]:
        """Every joint to 0 rad: ROBOTIS's offset-tuner posture (see the module's docstring)."""
        return self.robot.pose(dict.fromkeys(self.offsets, 0.0), duration=duration)

    def save(self, path: str | os.PathLike[str] | None = None) -> Path:
        """Write every offset to the user config (``[robot.joints.<name>] offset_deg``)."""
        return set_joint_offsets(self.offsets, path)
