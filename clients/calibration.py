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
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from config.user_file import set_joint_offsets

if TYPE_CHECKING:
    from pathlib import Path

    from clients.commander import Commander


def partner(name: str) -> str | None:
    """The joint on the other side (``r_knee`` ↔ ``l_knee``), None for the head."""
    if name.startswith("r_"):
        return "l_" + name[2:]
    if name.startswith("l_"):
        return "r_" + name[2:]
    return None


@dataclass
class _Sent:
    """A change sent and not answered yet: what the view showed before it, and what undoing
    it took from the history (put back should the daemon refuse it)."""

    before: dict[str, float]
    entry: dict[str, float] | None  # the history entry this change added
    undone: dict[str, float] | None  # the history entry an undo took


class OffsetEdits:
    """The editing logic shared by :class:`OffsetTuner` and the TUI's calibration view: the
    offsets as shown (the daemon's last answer with the changes sent since) and the history of
    changes; each method returns the ``{joint: degrees}`` to send with ``offsets`` ``op: set``
    (nothing is sent here) and shows it at once, so a key pressed again before the daemon has
    answered nudges a step further. Answers come in the order the changes were sent."""

    def __init__(self, offsets: dict[str, float] | None = None) -> None:
        self.offsets: dict[str, float] = dict(offsets or {})
        self.history: list[dict[str, float]] = []  # offsets before each change, newest last
        self._unanswered: list[_Sent] = []

    @property
    def pending(self) -> int:
        """Changes sent and not answered yet."""
        return len(self._unanswered)

    def applied(self, offsets: dict[str, float], *, answers_change: bool = True) -> None:
        """The daemon's answer: what the offsets are now (to a change, or to a ``get`` with
        ``answers_change=False``). While later changes are unanswered the view is newer than
        this answer and stays; the last answer, which includes them all, replaces it."""
        if answers_change and self._unanswered:
            self._unanswered.pop(0)
        if not self._unanswered:
            self.offsets = dict(offsets)

    def refused(self) -> None:
        """The oldest unanswered change was refused: nothing changed on the daemon. With no
        other change in flight the view goes back to what it was; otherwise the caller asks
        the daemon (``get``) once they are answered."""
        if not self._unanswered:
            return
        sent = self._unanswered.pop(0)
        if sent.entry is not None:
            self.history[:] = [h for h in self.history if h is not sent.entry]
        if sent.undone is not None:
            self.history.append(sent.undone)
        if not self._unanswered:
            self.offsets = sent.before

    def _sent(
        self,
        changes: dict[str, float],
        *,
        entry: dict[str, float] | None = None,
        undone: dict[str, float] | None = None,
    ) -> dict[str, float]:
        if changes:
            self._unanswered.append(_Sent(dict(self.offsets), entry, undone))
            self.offsets.update(changes)
        elif entry is not None:
            self.history.pop()  # nothing to send: nothing to undo either
        return changes

    def _change(self, changes: dict[str, float]) -> dict[str, float]:
        entry = dict(self.offsets)
        self.history.append(entry)
        return self._sent(changes, entry=entry)

    def nudge(self, joint: str, delta_deg: float) -> dict[str, float]:
        return self._change({joint: self.offsets[joint] + delta_deg})

    def mirror(self, joint: str) -> dict[str, float]:
        """``joint``'s partner on the other side gets the mirrored offset. The DARwIn-OP's left
        and right servos are mounted as mirror images (ROBOTIS's pages hold 2048 ± x for a pair
        in a symmetric pose), so the same correction is the opposite servo turn."""
        other = partner(joint)
        if other is None:
            raise ValueError(f"{joint} has no partner on the other side to mirror to")
        return self._change({other: -self.offsets[joint]})

    def reset(self, joints: list[str] | None = None) -> dict[str, float]:
        return self._change(dict.fromkeys(joints or list(self.offsets), 0.0))

    def undo(self) -> dict[str, float]:
        """The changes that restore the offsets before the last change (empty: nothing)."""
        if not self.history:
            raise ValueError("nothing to undo")
        before = self.history.pop()
        changes = {k: v for k, v in before.items() if self.offsets.get(k) != v}
        return self._sent(changes, undone=before)


class OffsetTuner:
    """Nudge, mirror, undo, reset and save the joints' offsets on a live daemon."""

    def __init__(self, robot: Commander) -> None:
        self.robot = robot
        self.edits = OffsetEdits()
        self._read = False

    @property
    def offsets(self) -> dict[str, float]:
        """The daemon's offsets (degrees by joint name), as last read or set."""
        if not self._read:
            self.refresh()
        return dict(self.edits.offsets)

    @property
    def history(self) -> list[dict[str, float]]:
        return self.edits.history

    def refresh(self) -> dict[str, float]:
        answer = self.robot.command("offsets", op="get")["offsets"]
        self.edits.applied(answer, answers_change=False)
        self._read = True
        return dict(self.edits.offsets)

    def _send(self, changes: dict[str, float]) -> dict[str, float]:
        if changes:
            self.edits.applied(self.robot.command("offsets", op="set", offsets=changes)["offsets"])
        return dict(self.edits.offsets)

    def _edit(self, make: Callable[[], dict[str, float]]) -> dict[str, float]:
        self.offsets  # noqa: B018 (read them first)
        changes = make()
        try:
            return self._send(changes)
        except Exception:
            self.edits.refused()
            raise

    def set(self, changes: dict[str, float]) -> dict[str, float]:
        """Set some joints' offsets (degrees); :meth:`undo` restores the previous ones."""
        return self._edit(lambda: self.edits._change(dict(changes)))

    def nudge(self, joint: str, delta_deg: float) -> dict[str, float]:
        return self._edit(lambda: self.edits.nudge(joint, delta_deg))

    def mirror(self, joint: str) -> dict[str, float]:
        return self._edit(lambda: self.edits.mirror(joint))

    def reset(self, joints: list[str] | None = None) -> dict[str, float]:
        """Offsets back to 0 (every joint, or ``joints``); undoable."""
        return self._edit(lambda: self.edits.reset(joints))

    def undo(self) -> dict[str, float]:
        return self._edit(self.edits.undo)

    def reference_pose(self, duration: float = 2.0) -> dict[str, Any]:
        """Every joint to 0 rad: ROBOTIS's offset-tuner posture (see the module's docstring)."""
        return self.robot.pose(dict.fromkeys(self.offsets, 0.0), duration=duration)

    def save(self, path: str | os.PathLike[str] | None = None) -> Path:
        """Write every offset to the user config (``[robot.joints.<name>] offset_deg``)."""
        return set_joint_offsets(self.offsets, path)
