"""The ``offsets`` verb: the joints' calibration offsets, read by anyone and set live by an
admin holding the lease (``{"op": "set", "offsets": {"r_knee": 1.5}}``, degrees).

A new offset takes effect at the next goal written: ``servo = direction · joint + offset``
(:mod:`robot_daemon.bus.calibration`), as ROBOTIS's framework adds ``m_Offset[id]`` to every
goal. The daemon does not write any file: the client saves the offsets to the user's config
(``clients/calibration.py``), so a restart keeps them.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from config.loader import RobotConfig
from robot_daemon.arbiter import fields as F
from robot_daemon.arbiter.registry import MotionContext, Request, verb
from schemas import units
from schemas.errors import ErrorCode, Reject, brief

# ROBOTIS's tuner nudges by steps; a calibration beyond this is a mistake, not an offset.
MAX_OFFSET_DEG = 512 * units.DEG_PER_UNIT  # 45°


def current(robot: RobotConfig) -> dict[str, float]:
    return {j.name: j.offset_deg for j in robot.joints}


def _apply(robot: RobotConfig, changes: dict[int, float]) -> None:
    """Replace the joints' configs in the daemon's one :class:`RobotConfig` (every context,
    the ``config`` reply and register reads see the new offsets)."""
    joints = tuple(
        dataclasses.replace(j, offset_deg=changes[j.id]) if j.id in changes else j
        for j in robot.joints
    )
    object.__setattr__(robot, "joints", joints)  # frozen for callers; this verb is its writer
    for j in joints:
        robot.by_id[j.id] = j
        robot.by_name[j.name] = j


@verb("offsets")
def offsets(req: Request, ctx: MotionContext) -> dict[str, Any]:
    op = req.op.name
    given = req.fields.get("offsets")
    if op == "get":
        return {"offsets": current(ctx.robot)}
    if not isinstance(given, dict) or not given:
        raise Reject(
            ErrorCode.INVALID,
            f"offsets must be a map of joint → degrees, got {brief(given)}",
            "offsets",
        )
    changes: dict[int, float] = {}
    for key, value in given.items():
        joint = F.joint_ref(ctx.robot, key, "offsets")
        deg = F.number({"offsets": value}, "offsets")
        if not math.isfinite(deg) or abs(deg) > MAX_OFFSET_DEG:
            raise Reject(
                ErrorCode.OUT_OF_RANGE,
                f"offset of {joint.name} {deg}° is beyond ±{MAX_OFFSET_DEG:.0f}°",
                "offsets",
            )
        changes[joint.id] = float(deg)
    for jid, deg in changes.items():
        ctx.bus.calibration.set_offset(jid, deg)
    _apply(ctx.robot, changes)
    names = ", ".join(f"{ctx.robot.joint(j).name} {d:+.2f}°" for j, d in changes.items())
    ctx.emit("offsets", f"offsets set: {names}", offsets=current(ctx.robot))
    return {"offsets": current(ctx.robot)}
