"""Editing action pages: the model behind the TUI's Actions tab and the ``Robot`` client's teach
helpers. Pure (no Textual, no Zenoh): a page is the table the ``pages`` verb sends and a TOML
page file holds — ``number``, ``name``, ``repeat``, ``schedule``, ``speed``, ``accel``,
``next``, ``exit`` and ``step``, a list of ``{time, pause, <joint>: degrees…}`` (a joint left
out of a step is not driven by it). Every change can be undone.

Joint groups name what teach mode makes limp: a joint's name, ``right_arm``, ``left_arm``,
``arms``, ``right_leg``, ``left_leg``, ``legs``, ``head`` or ``all``.

Mirroring (hardware.md): the servos of the two sides are mounted mirrored, so the same motion
on the other side is the negated angle, for every left/right pair; on the body's middle, head
pan turns the other way (negated) and head tilt stays.
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from schemas.errors import DarwinError
from schemas.joints import JOINT_NAMES
from schemas.units import deg_to_raw, raw_to_deg

JOINTS: tuple[str, ...] = JOINT_NAMES  # by id 1..20, the config's names
ARM = ("shoulder_pitch", "shoulder_roll", "elbow")
LEG = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
GROUPS: dict[str, tuple[str, ...]] = {
    "right_arm": tuple(f"r_{j}" for j in ARM),
    "left_arm": tuple(f"l_{j}" for j in ARM),
    "right_leg": tuple(f"r_{j}" for j in LEG),
    "left_leg": tuple(f"l_{j}" for j in LEG),
    "head": ("head_pan", "head_tilt"),
}
GROUPS["arms"] = GROUPS["right_arm"] + GROUPS["left_arm"]
GROUPS["legs"] = GROUPS["right_leg"] + GROUPS["left_leg"]
GROUPS["all"] = JOINTS
LEGS = frozenset(GROUPS["legs"])
MIDDLE_SIGN = {"head_pan": -1.0, "head_tilt": 1.0}  # mirrored sign of the joints on the middle
HEADER = ("number", "name", "repeat", "schedule", "speed", "accel", "next", "exit")
STEP_KEYS = ("time", "pause")
MAX_UNDO = 200
DEFAULT_TIME = 100  # time units (0.8 s at speed 32) of a new step


class EditError(DarwinError, ValueError):
    """An edit that cannot be made (unknown joint or group, no such step)."""


def joints_of(spec: str | Iterable[str], known: Sequence[str] = JOINTS) -> list[str]:
    """Joint names for a group name, a joint name or a list of either, in id order."""
    items = [spec] if isinstance(spec, str) else list(spec)
    wanted: set[str] = set()
    for item in items:
        if item in GROUPS:
            wanted |= set(GROUPS[item])
        elif item in known:
            wanted.add(item)
        else:
            raise EditError(
                f"unknown joint or group {item!r}: groups are {', '.join(GROUPS)}; "
                f"joints are {', '.join(known)}"
            )
    return [j for j in known if j in wanted]


def quantize(degrees: float) -> float:
    """The angle a page can hold (the servo's raw step, two decimals): what is shown is what
    is saved and played."""
    return round(float(raw_to_deg(deg_to_raw(degrees))), 2)


def mirror_name(joint: str) -> str:
    if joint.startswith("r_"):
        return "l_" + joint[2:]
    if joint.startswith("l_"):
        return "r_" + joint[2:]
    return joint


def mirror_value(joint: str, degrees: float) -> float:
    sign = MIDDLE_SIGN.get(joint, -1.0)
    return quantize(sign * degrees) if degrees else 0.0


def blank_page(number: int, name: str = "") -> dict[str, Any]:
    return {
        "number": number,
        "name": name or f"page {number}",
        "repeat": 1,
        "schedule": "time",
        "speed": 32,
        "accel": 32,
        "next": 0,
        "exit": 0,
        "step": [],
    }


def step_pose(step: Mapping[str, Any], known: Sequence[str] = JOINTS) -> dict[str, float]:
    """The joints a step drives, in degrees."""
    return {j: float(step[j]) for j in known if j in step}


def step_seconds(page: Mapping[str, Any], step: Mapping[str, Any]) -> float:
    """How long a time-based step takes to play (one unit is 8 ms at speed 32)."""
    return max(int(step.get("time", 1)), 1) * 0.008 * 32.0 / max(int(page.get("speed", 32)), 1)


class PageEditor:
    """One page being edited. Every method that changes it can be undone with :meth:`undo`."""

    def __init__(self, page: Mapping[str, Any], known: Sequence[str] = JOINTS) -> None:
        self.page: dict[str, Any] = copy.deepcopy(dict(page))
        self.page.setdefault("step", [])
        self.known = tuple(known)
        self._undo: list[dict[str, Any]] = []
        self.dirty = False

    # -- history -------------------------------------------------------------------------------
    def _change(self) -> None:
        self._undo.append(copy.deepcopy(self.page))
        del self._undo[:-MAX_UNDO]
        self.dirty = True

    def undo(self) -> bool:
        """Go back one change; False when there is nothing to undo."""
        if not self._undo:
            return False
        self.page = self._undo.pop()
        self.dirty = True
        return True

    # -- reading -------------------------------------------------------------------------------
    @property
    def steps(self) -> list[dict[str, Any]]:
        return self.page["step"]

    def step(self, k: int) -> dict[str, Any]:
        if not 0 <= k < len(self.steps):
            raise EditError(f"no step {k + 1}: the page has {len(self.steps)} steps")
        return self.steps[k]

    def _joint(self, joint: str) -> str:
        if joint not in self.known:
            raise EditError(f"unknown joint {joint!r}; joints are {', '.join(self.known)}")
        return joint

    # -- the page's header -----------------------------------------------------------------------
    def set_field(self, key: str, value: Any) -> None:
        """``number``, ``name``, ``repeat``, ``schedule``, ``speed``, ``accel``, ``next`` or
        ``exit`` (the daemon checks the values when the page is saved)."""
        if key not in HEADER:
            raise EditError(f"unknown page field {key!r}; fields are {', '.join(HEADER)}")
        if self.page.get(key) == value:
            return
        self._change()
        self.page[key] = value

    # -- values --------------------------------------------------------------------------------
    def set_value(self, k: int, joint: str, degrees: float | None) -> None:
        """A joint's angle in step ``k`` (0-based); ``None``: the step does not drive it."""
        step = self.step(k)
        self._joint(joint)
        self._change()
        if degrees is None:
            step.pop(joint, None)
        else:
            step[joint] = quantize(degrees)

    def nudge(self, k: int, joint: str, delta: float) -> float:
        step = self.step(k)
        value = quantize(float(step.get(self._joint(joint), 0.0)) + delta)
        self.set_value(k, joint, value)
        return value

    def set_time(self, k: int, time: int | None = None, pause: int | None = None) -> None:
        step = self.step(k)
        self._change()
        if time is not None:
            step["time"] = int(time)
        if pause is not None:
            step["pause"] = int(pause)

    # -- steps ---------------------------------------------------------------------------------
    def insert_step(self, k: int, pose: Mapping[str, float] | None = None) -> int:
        """A new step at index ``k`` (0..len); its pose is ``pose``, else that of the step
        before it (or after it, when inserted first). Returns its index."""
        if not 0 <= k <= len(self.steps):
            raise EditError(f"cannot insert at step {k + 1}: the page has {len(self.steps)}")
        if pose is None:
            near = self.steps[k - 1] if k > 0 else (self.steps[0] if self.steps else {})
            pose = step_pose(near, self.known)
        self._change()
        new: dict[str, Any] = {"time": DEFAULT_TIME, "pause": 0}
        new.update({self._joint(j): quantize(v) for j, v in pose.items()})
        self.steps.insert(k, new)
        return k

    def duplicate_step(self, k: int) -> int:
        step = copy.deepcopy(self.step(k))
        self._change()
        self.steps.insert(k + 1, step)
        return k + 1

    def delete_step(self, k: int) -> None:
        self.step(k)
        self._change()
        del self.steps[k]

    def move_step(self, k: int, delta: int) -> int:
        """Move step ``k`` by ``delta`` places; returns its new index."""
        self.step(k)
        to = k + delta
        if not 0 <= to < len(self.steps):
            raise EditError(f"step {k + 1} cannot move to {to + 1}")
        self._change()
        self.steps.insert(to, self.steps.pop(k))
        return to

    def mirror(self, k: int, source: str | None = None) -> None:
        """Mirror step ``k`` left↔right: ``source`` None swaps the sides (the whole motion
        mirrored); ``"right"`` copies the right side onto the left, ``"left"`` the reverse."""
        step = self.step(k)
        if source not in (None, "right", "left"):
            raise EditError(f"mirror source must be 'right', 'left' or None, got {source!r}")
        before = step_pose(step, self.known)
        if source is None:
            targets = list(self.known)
        else:
            prefix = "l_" if source == "right" else "r_"
            targets = [j for j in self.known if j.startswith(prefix)]
        self._change()
        for joint in targets:
            other = mirror_name(joint)
            if other in before:
                step[joint] = mirror_value(other, before[other])
            else:
                step.pop(joint, None)

    def capture(
        self, k: int, positions: Mapping[str, float], joints: Iterable[str] | None = None
    ) -> dict[str, float]:
        """Store the present angles (degrees by joint name) in step ``k`` for ``joints``
        (default: every joint in ``positions``). Returns what was stored."""
        step = self.step(k)
        chosen = list(positions) if joints is None else [self._joint(j) for j in joints]
        missing = [j for j in chosen if j not in positions]
        if missing:
            raise EditError(f"no present position for {', '.join(missing)}")
        self._change()
        stored = {j: quantize(positions[j]) for j in chosen if j in self.known}
        step.update(stored)
        return stored
