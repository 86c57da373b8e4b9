"""The ``policy`` verb: start, steer, stop and read the policy stream (schemas/policy.py).

``start`` answers the lease holder alone with the stream key its actions are signed with
(the reply to a query goes to the querier only; the key is never published).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from robot_daemon.arbiter import fields as F
from robot_daemon.arbiter.limp import refuse_limp
from robot_daemon.arbiter.registry import MotionContext, Request, verb
from robot_daemon.motion.policy import PolicyModule
from schemas.joints import JOINT_IDS, JOINT_NAMES
from schemas.keys import Keys
from schemas.policy import DEFAULT_POSE, MODES, RATE_RANGE

MAX_COMMAND = 2.0  # |x|, |y| m/s and |turn| rad/s of the command the policy observes


@verb("policy")
def policy(req: Request, ctx: MotionContext) -> dict[str, Any]:
    module: PolicyModule = ctx.module("policy", PolicyModule, "the policy loop")
    op = req.op.name
    if op == "status":
        st = dataclasses.asdict(module.policy_status())
        return {"op": op, **st}
    if op == "stop":
        module.stop()
        return {"op": op, "state": module.state, "reason": module.reason}
    if op == "command":
        x, y, turn = (
            F.number(req.fields, k, -MAX_COMMAND, MAX_COMMAND, default=0.0)
            for k in ("x", "y", "turn")
        )
        module.set_command(x, y, turn)
        return {"op": op, "command": module.command}
    s = module.settings
    tick_hz = 1000.0 / ctx.info.tick_ms if ctx.info is not None else RATE_RANGE[1]
    rate = F.number(req.fields, "rate_hz", RATE_RANGE[0], min(RATE_RANGE[1], tick_hz), s.rate_hz)
    mode = F.text(req.fields, "mode", set(MODES), default="offset")
    scale = F.number(req.fields, "scale", 0.01, 1.0, default=s.scale)
    refuse_limp(ctx, JOINT_IDS, "the policy loop")  # it drives all 20 joints
    key = module.start(req.client, rate, mode, scale)
    keys = Keys(ctx.info.robot) if ctx.info is not None else None
    return {
        "op": op,
        "stream_key": key,
        "tick": module.started_tick,  # observations after this tick are of the stream
        "client": req.client,
        "rate_hz": rate,
        "mode": mode,
        "scale": scale,
        "max_delta": s.max_delta,
        "joints": list(JOINT_NAMES),
        "default_pose": list(DEFAULT_POSE),
        "low": module.low.tolist(),
        "high": module.high.tolist(),
        "keys": {w: keys.policy(w) for w in ("obs", "action", "applied", "status")} if keys else {},
    }
