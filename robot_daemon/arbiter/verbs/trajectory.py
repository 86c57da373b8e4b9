"""The `trajectory` verb: a whole joint trajectory, checked at once, played in the loop.

Every point is checked before anything moves (joints known, online and with torque, positions
finite and inside the limits, times increasing, no segment faster than the servos can go, from
the joints' present positions to the first point too); a bad point refuses the whole trajectory,
naming it. Then :class:`DirectModule` plays it tick by tick, so its timing is the loop's, not
the network's.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from robot_daemon.arbiter import fields as F
from robot_daemon.arbiter.registry import MotionContext, Reject, Request, verb
from robot_daemon.arbiter.verbs.basic import _check_online, _direct
from robot_daemon.motion.trajectory import Trajectory
from schemas.errors import ErrorCode, brief

MAX_TRAJECTORY_S = 600.0


def _list(value: Any, name: str) -> list[Any]:
    if not isinstance(value, list | tuple) or not value:
        raise Reject(ErrorCode.INVALID, f"{name} must be a non-empty list, got {brief(value)}",
                     name)
    return list(value)


def _point(raw: Any, k: int, width: int) -> tuple[float, list[Any]]:
    name = f"points[{k}]"
    if not isinstance(raw, dict):
        raise Reject(ErrorCode.INVALID, f"{name} must be a map {{t, positions}}", name)
    unknown = set(raw) - {"t", "positions"}
    if unknown:
        field = sorted(map(str, unknown))[0]
        raise Reject(ErrorCode.INVALID, f"{name} has an unknown field {field!r} (fields: t, "
                     "positions)", f"{name}.{field}")
    t = F.number(raw, "t")
    positions = _list(raw.get("positions"), f"{name}.positions")
    if len(positions) != width:
        raise Reject(ErrorCode.INVALID, f"{name} has {len(positions)} positions for {width} "
                     "joints", f"{name}.positions")
    return t, positions


def check_trajectory(req: Request, ctx: MotionContext) -> Trajectory:
    refs = _list(req.fields.get("joints"), "joints")
    joints = [F.joint_ref(ctx.robot, v, f"joints[{i}]") for i, v in enumerate(refs)]
    ids = [j.id for j in joints]
    if len(set(ids)) != len(ids):
        raise Reject(ErrorCode.INVALID, "joints names a joint twice", "joints")
    for i, jid in enumerate(ids):
        _check_online(ctx, jid, f"joints[{i}]", "trajectory")
    raw_points = _list(req.fields.get("points"), "points")
    times: list[float] = []
    rows: list[list[float]] = []
    frame = ctx.frame
    prev_t = 0.0
    prev = [float(frame.position[j]) if frame is not None else math.nan for j in ids]
    for k, raw in enumerate(raw_points):
        t, positions = _point(raw, k, len(ids))
        if not t > prev_t:
            raise Reject(ErrorCode.INVALID, f"points[{k}].t = {t:.3f} s must be after "
                         f"{prev_t:.3f} s", f"points[{k}].t")
        if t > MAX_TRAJECTORY_S:
            raise Reject(ErrorCode.OUT_OF_RANGE, f"points[{k}].t = {t:.1f} s is longer than "
                         f"{MAX_TRAJECTORY_S:.0f} s", f"points[{k}].t")
        row = [F.joint_position(j, v, f"points[{k}].positions[{i}]")
               for i, (j, v) in enumerate(zip(joints, positions, strict=True))]
        for i, (j, a, b) in enumerate(zip(joints, prev, row, strict=True)):
            speed = abs(b - a) / (t - prev_t)
            if speed > ctx.robot.max_speed:
                raise Reject(
                    ErrorCode.OUT_OF_RANGE,
                    f"points[{k}]: {j.name} would move at {speed:.2f} rad/s, faster than the "
                    f"servos' {ctx.robot.max_speed:.2f} rad/s: give it more time",
                    f"points[{k}].positions[{i}]",
                )
        times.append(t)
        rows.append(row)
        prev_t, prev = t, row
    return Trajectory(tuple(ids), np.array(times), np.array(rows))


@verb("trajectory")
def trajectory(req: Request, ctx: MotionContext) -> dict[str, Any]:
    direct = _direct(ctx)
    if req.op.name == "stop":
        return {"stopped": direct.stop_trajectory()}
    traj = check_trajectory(req, ctx)
    direct.set_trajectory(traj)
    return {
        "joints": [ctx.robot.by_id[j].name for j in traj.ids],
        "points": len(traj.times),
        "duration": traj.duration,
    }
