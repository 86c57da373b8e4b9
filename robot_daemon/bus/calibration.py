"""Joint calibration, defined once: ``servo = direction · joint + offset``.

Raw positions are converted to servo angles by :mod:`schemas.units`; the direction and offset
come from the robot config. The functions work on one joint (scalars) or on every joint at once
(arrays indexed by joint id), with the same arithmetic.
"""

from __future__ import annotations

import math
from typing import Any, TypeVar, cast

import numpy as np

from config.loader import JointConfig, RobotConfig
from robot_daemon.frames import N_SLOTS
from robot_daemon.hotpath import compiled as _compiled
from schemas import units

Angles = TypeVar("Angles", float, np.ndarray)
# goals_raw's columns of a set of joints: sign, offset, lower and upper limit as goal_raw tests
# them, and whether every goal within the limits lands inside the servo's range.
_Columns = tuple[list[float], list[float], list[float], list[float], bool]


def servo_to_joint(raw: Angles, direction: Angles, offset_rad: Angles) -> Angles:
    """Joint angle (rad) for a raw servo position (one joint, or arrays of every joint)."""
    angle: Angles = direction * (units.raw_to_rad(raw) - offset_rad)
    return angle


def joint_to_servo(rad: float, direction: float, offset_rad: float) -> int:
    """Raw servo position for a joint angle, kept inside the servo's 0..4095."""
    raw = units.rad_to_raw(direction * rad + offset_rad)
    return max(0, min(units.POSITION_MAX, raw))


def joint_angle(joint: JointConfig, raw: int | float) -> float:
    """:func:`servo_to_joint` for one configured joint."""
    return float(servo_to_joint(raw, joint.direction, math.radians(joint.offset_deg)))


def joint_raw(joint: JointConfig, rad: float) -> int:
    """:func:`joint_to_servo` for one configured joint."""
    return joint_to_servo(rad, joint.direction, math.radians(joint.offset_deg))


def goals_raw_py(sign: list[float], offset: list[float], lo: list[float], hi: list[float],
                 rads: list[float], k: float, c: int) -> list[int] | None:
    """``round((s · r + o) / k) + c`` of each goal ``r`` with its joint's sign, offset and
    limits, or None when one is not within its limits (a NaN is neither below nor above: it is
    refused too). The definition of what ``robot_daemon/_hotpath.c`` computes for
    :meth:`Calibration.goals_raw` where it is built."""
    raws = [
        round((s * r + o) / k) + c if lo_ <= r <= hi_ else None
        for s, r, o, lo_, hi_ in zip(sign, rads, offset, lo, hi, strict=True)
    ]
    return None if None in raws else cast("list[int]", raws)


class Calibration:
    """Direction, offset and limits of every joint, as arrays indexed by joint id."""

    def __init__(self, robot: RobotConfig) -> None:
        self.sign = np.ones(N_SLOTS)
        self.offset = np.zeros(N_SLOTS)
        self.min = np.full(N_SLOTS, -math.pi)
        self.max = np.full(N_SLOTS, math.pi)
        for j in robot.joints:
            self.sign[j.id] = j.direction
            self.offset[j.id] = math.radians(j.offset_deg)
            self.min[j.id], self.max[j.id] = j.min_rad, j.max_rad
        self._lists()

    def _lists(self) -> None:
        # The same figures as plain lists for :meth:`goal_raw`, which runs for every goal of
        # every tick: indexing a list costs a fraction of indexing a numpy array.
        self._sign, self._offset = self.sign.tolist(), self.offset.tolist()
        self._min, self._max = self.min.tolist(), self.max.tolist()
        # goals_raw's columns by the joints written (a handful of sets in use).
        self._columns: dict[tuple[int, ...], _Columns] = {}

    @property
    def angle_columns(self) -> tuple[list[float], list[float]]:
        """Sign and offset of every slot as :meth:`positions_list` computes with them (for the
        compiled snapshot, engine/snapshot.py)."""
        return self._sign, self._offset

    def set_offset(self, jid: int, offset_deg: float) -> None:
        """A new offset for joint ``jid``, used from the next conversion on (the next goal
        written shifts by the change)."""
        self.offset[jid] = math.radians(offset_deg)
        self._lists()

    def to_joint(self, jid: int, raw: int | float) -> float:
        return float(servo_to_joint(raw, self.sign[jid], self.offset[jid]))

    def to_raw(self, jid: int, rad: float) -> int:
        return joint_to_servo(rad, float(self.sign[jid]), float(self.offset[jid]))

    def positions(self, raw: np.ndarray) -> np.ndarray:
        """Joint angles of every slot at once (slot 0 is unused and stays meaningless)."""
        return servo_to_joint(raw, self.sign, self.offset)

    def joint_arrays(
        self, position: np.ndarray, speed: np.ndarray, load: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint angles, speeds (rad/s) and loads (signed fraction) of every slot from the
        servos' raw words, as the frame wants them: by the compiled conversion where it is
        built (one call filling one 3-row array: the same bits, tests/unit/test_hotpath.py),
        else by :meth:`joint_arrays_py`, their definition."""
        if _compiled is not None:
            out = np.empty((3, len(position)))
            if _compiled.joint_arrays(
                position, speed, load, self.sign, self.offset, units.SPEED_RAD_S_TABLE,
                units.LOAD_FRACTION_TABLE, units.RAD_PER_UNIT, units.POSITION_CENTER, out,
            ) is True:
                return out[0], out[1], out[2]
        return self.joint_arrays_py(position, speed, load)

    def joint_arrays_py(
        self, position: np.ndarray, speed: np.ndarray, load: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`joint_arrays` in numpy: :meth:`positions`, and each speed and load word's
        table entry times the joint's direction."""
        return (
            self.positions(position),
            self.sign * units.SPEED_RAD_S_TABLE[speed & 0x7FF],
            self.sign * units.LOAD_FRACTION_TABLE[load & 0x7FF],
        )

    def positions_list(self, raw: list[int]) -> list[float]:
        """:meth:`positions` on plain lists (every slot), in the same order of operations, so
        the same bits: on 21 values, cheaper than one numpy operation."""
        k, c = units.RAD_PER_UNIT, units.POSITION_CENTER
        if _compiled is not None:  # the same bits (tests/unit/test_hotpath.py)
            out = _compiled.positions_list(raw, self._sign, self._offset, k, c)
            if out is not NotImplemented:
                return cast("list[float]", out)
        pairs = zip(raw, self._sign, self._offset, strict=True)
        return [s * ((r - c) * k - o) for r, s, o in pairs]

    def goal_raw(self, jid: int, rad: float) -> tuple[int, bool]:
        """A goal to write: (raw position, whether it was outside the joint's limits and
        clamped). The same conversion as :meth:`to_raw` after :meth:`clamp` (``round`` is
        half-even), on plain floats: 20 goals a tick cost less this way than as arrays."""
        lo, hi = self._min[jid], self._max[jid]
        clamped = rad < lo - 1e-9 or rad > hi + 1e-9
        if clamped:
            rad = lo if rad < lo else hi
        raw = int(round((self._sign[jid] * rad + self._offset[jid]) / units.RAD_PER_UNIT))
        raw += units.POSITION_CENTER
        return (0 if raw < 0 else units.POSITION_MAX if raw > units.POSITION_MAX else raw), clamped

    def goals_raw(self, ids: tuple[int, ...], rads: list[float]) -> list[int] | None:
        """:meth:`goal_raw` of every goal of a tick at once (``ids`` and their ``rads`` in the
        same order), or None when one is outside its joint's limits or not a number: the
        caller then converts them one by one, clamping and counting. The same arithmetic, run
        by one comprehension over columns made once per set of joints (18 calls of
        :meth:`goal_raw` cost twice as much)."""
        cols = self._columns.get(ids)
        if cols is None:
            if len(self._columns) > 64:
                self._columns.clear()
            cols = self._columns[ids] = self._goal_columns(ids)
        sign, offset, lo, hi, inside = cols
        k, c = units.RAD_PER_UNIT, units.POSITION_CENTER
        # The compiled conversion where it is built (the same bits: tests/unit/test_hotpath.py);
        # it hands back NotImplemented for what only the Python takes (a goal not a float).
        raws: Any = NotImplemented if _compiled is None else _compiled.goals_raw(
            sign, offset, lo, hi, rads, k, c)
        if raws is NotImplemented:
            raws = goals_raw_py(sign, offset, lo, hi, rads, k, c)
        if raws is None:
            return None
        if not inside:
            top = units.POSITION_MAX
            return [0 if r < 0 else top if r > top else r for r in cast("list[int]", raws)]
        return cast("list[int]", raws)

    def _goal_columns(self, ids: tuple[int, ...]) -> _Columns:
        """Sign, offset and the limits goal_raw tests of each joint of ``ids``, and whether
        every goal within them lands inside the servo's 0..4095: the conversion is monotonic
        (each IEEE operation and ``round`` are), so the ends' goals bound every other."""
        sign = [self._sign[j] for j in ids]
        offset = [self._offset[j] for j in ids]
        lo = [self._min[j] - 1e-9 for j in ids]
        hi = [self._max[j] + 1e-9 for j in ids]
        k, c, top = units.RAD_PER_UNIT, units.POSITION_CENTER, units.POSITION_MAX
        ends = [round((s * r + o) / k) + c for s, o, a, b in zip(sign, offset, lo, hi, strict=True)
                for r in (a, b)]
        return sign, offset, lo, hi, all(0 <= e <= top for e in ends)

    def in_limits(self, jid: int, rad: float) -> bool:
        return bool(self.min[jid] - 1e-9 <= rad <= self.max[jid] + 1e-9)

    def clamp(self, jid: int, rad: float) -> float:
        return float(min(max(rad, self.min[jid]), self.max[jid]))
