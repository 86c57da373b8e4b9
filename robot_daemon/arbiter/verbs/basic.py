"""The basic verbs: lease, joint, pose, torque, led, halt, power, config, registers.

Every value is checked before anything is queued or written; a handler that raises ``Reject``
has touched nothing. Bus failures become ``unavailable`` errors that say what to do.
"""

from __future__ import annotations

from typing import Any

from robot_daemon.arbiter import fields as F
from robot_daemon.arbiter.lease import Lease
from robot_daemon.arbiter.limp import refuse_limp
from robot_daemon.arbiter.protected import is_protected
from robot_daemon.arbiter.registry import MotionContext, Reject, Request, verb
from robot_daemon.bus.calibration import joint_angle
from robot_daemon.bus.tables import CM730, CM730_TABLE_SIZE, MX28, MX28_TABLE_SIZE
from robot_daemon.motion.direct import DirectModule
from schemas import units
from schemas.commands import LeaseOp
from schemas.errors import BusError, ErrorCode, brief

MAX_POSE_DURATION = 60.0


def _bus_error(exc: BusError) -> Reject:
    return Reject(ErrorCode.UNAVAILABLE, f"{exc} (see status.bus)")


def _direct(ctx: MotionContext) -> DirectModule:
    return ctx.module("direct", DirectModule, "direct joint control")


def _check_online(ctx: MotionContext, jid: int, field_name: str, what: str) -> None:
    refuse_limp(ctx, (jid,), what, field_name)


@verb("lease")
def lease(req: Request, ctx: MotionContext) -> dict[str, Any]:
    op = req.op.name
    state: Lease | None = ctx.lease
    if state is None:
        raise Reject(ErrorCode.UNAVAILABLE, "this daemon has no control lease")
    if op == LeaseOp.ACQUIRE:
        holder = state.acquire(req.client, req.name, req.token)
        # The token goes to this caller alone: it binds the lease to the session that took it.
        return {
            "op": op,
            "holder": holder.to_dict(),
            "you": True,
            "token": holder.token,
            "heartbeat_timeout": state.heartbeat_timeout,
        }
    if op == LeaseOp.RELEASE:
        released = state.release(req.client, req.token)
        return {"op": op, "released": released, "holder": state.status()}
    if op == LeaseOp.RENEW:
        state.renew(req.client, req.token)
        return {"op": op, "holder": state.status(), "you": True}
    h = state.holder
    return {
        "op": op,
        "holder": state.status(),
        "you": bool(h and h.client == req.client and h.token == req.token),
        "idle_timeout": state.idle_timeout,
        "heartbeat_timeout": state.heartbeat_timeout,
    }


@verb("joint")
def joint(req: Request, ctx: MotionContext) -> dict[str, Any]:
    key = "id" if req.fields.get("id") is not None else "name"
    j = F.joint_ref(ctx.robot, F.present(req.fields, key), key)
    position = F.joint_position(j, req.fields.get("position"), "position")
    speed = F.number(req.fields, "speed", 0.0, ctx.robot.max_speed, default=0.0)
    _check_online(ctx, j.id, key, "joint")
    # 0 (or absent) is the servo's maximum, as documented: say so explicitly, never let the
    # module's own default (a gentler speed for poses) stand in for it.
    applied_speed = speed or ctx.robot.max_speed
    _direct(ctx).set_joint(j.id, position, applied_speed)
    return {"id": j.id, "name": j.name, "position": position, "speed": applied_speed}


@verb("pose")
def pose(req: Request, ctx: MotionContext) -> dict[str, Any]:
    positions = F.present(req.fields, "positions")
    if not isinstance(positions, dict) or not positions:
        raise Reject(
            ErrorCode.INVALID,
            f"positions must be a non-empty map of joint → rad, got {positions!r}",
            "positions",
        )
    duration = F.number(req.fields, "duration", 0.0, MAX_POSE_DURATION, default=1.0)
    if duration <= 0:
        raise Reject(ErrorCode.OUT_OF_RANGE, "duration must be > 0 s", "duration")
    targets: dict[int, float] = {}
    for k, v in positions.items():
        field_name = f"positions.{k}"
        j = F.joint_ref(ctx.robot, k, field_name)
        targets[j.id] = F.joint_position(j, v, field_name)
        _check_online(ctx, j.id, field_name, "pose")
    _direct(ctx).set_pose(targets, duration)
    return {
        "positions": {ctx.robot.by_id[i].name: p for i, p in sorted(targets.items())},
        "duration": duration,
    }


@verb("torque")
def torque(req: Request, ctx: MotionContext) -> dict[str, Any]:
    enable = F.boolean(req.fields, "enable")
    raw_ids = req.fields.get("ids")
    if raw_ids is None:
        ids = list(ctx.robot.ids)
    else:
        if not isinstance(raw_ids, list) or not raw_ids:
            raise Reject(ErrorCode.INVALID, f"ids must be a non-empty list, got {raw_ids!r}", "ids")
        ids = [F.joint_ref(ctx.robot, v, f"ids[{i}]").id for i, v in enumerate(raw_ids)]
    frame = ctx.frame
    offline = [j for j in ids if frame is not None and not frame.online[j]]
    ids = [j for j in ids if j not in offline]
    # Torque off on a joint a motion drives stops that motion at the next tick, as any joint
    # going limp does (MotionManager.stop_limp); no goal is written to a torque-off joint.
    try:
        refused = ctx.bus.set_torque(ids, enable) or {}
    except BusError as exc:
        raise _bus_error(exc) from None
    if refused and len(refused) == len(ids):
        # Nothing was enabled: saying "on" would be a lie about a limp joint.
        raise Reject(
            ErrorCode.REFUSED,
            "; ".join(refused.values())
            + ": torque not enabled (it would re-arm the alarm); let it cool or take the load "
            "off, then ask again (status.alarms)",
            "ids",
        )
    out: dict[str, Any] = {
        "enable": enable, "ids": [j for j in ids if j not in refused], "offline": offline
    }
    if refused:
        out["alarmed"] = {str(j): why for j, why in refused.items()}
    return out


@verb("led")
def led(req: Request, ctx: MotionContext) -> dict[str, Any]:
    head = F.rgb(req.fields, "head")
    eye = F.rgb(req.fields, "eye")
    panel = None
    if req.fields.get("panel") is not None:
        panel = F.integer(req.fields, "panel", 0, 7)
    if head is None and eye is None and panel is None:
        raise Reject(ErrorCode.INVALID, "give at least one of head, eye, panel", "head")
    head_w = units.rgb_to_color_word(*head) if head else None
    eye_w = units.rgb_to_color_word(*eye) if eye else None
    try:
        ctx.bus.set_leds(head_w, eye_w, panel)
    except BusError as exc:
        raise _bus_error(exc) from None
    out: dict[str, Any] = {}
    if head_w is not None:
        out["head"] = list(units.color_word_to_rgb(head_w))
    if eye_w is not None:
        out["eye"] = list(units.color_word_to_rgb(eye_w))
    if panel is not None:
        out["panel"] = panel
    return out


@verb("halt")
def halt(req: Request, ctx: MotionContext) -> dict[str, Any]:
    # Pages, poses, trajectories, ball play, the policy freeze now; a walk ends its step at the
    # next double support (within half a period) and holds: frozen mid-step it stood on one
    # foot and tipped over. Limp at once is `torque` enable=false (or the reset button).
    ctx.manager.halt(finish_step=True)
    finishing = sorted(m.name for m in ctx.manager.modules if m.finishing)
    ctx.emit("halt", f"halt by {req.name!r}", client=req.client, finishing=finishing)
    return {"halted": True, "by": req.name, "finishing": finishing}


@verb("power")
def power(req: Request, ctx: MotionContext) -> dict[str, Any]:
    op = req.op.name
    if ctx.power is None:
        raise Reject(ErrorCode.UNAVAILABLE, "this daemon has no servo power switch")
    try:
        return {"op": op, **ctx.power.ask_power(op == "on", req.name)}
    except BusError as exc:
        raise _bus_error(exc) from None


@verb("config")
def config(req: Request, ctx: MotionContext) -> dict[str, Any]:
    info = ctx.info
    dcfg = ctx.settings.get("daemon", {})
    return {
        "robot": info.robot if info is not None else ctx.robot.name,
        "tick_ms": info.tick_ms if info is not None else dcfg.get("tick_ms", 8.0),
        "max_speed": ctx.robot.max_speed,
        "allow_eeprom": bool(ctx.extras.get("allow_eeprom")),
        "allow_hardware_writes": _hardware_writes(ctx),
        "lease_idle_timeout": ctx.settings.get("daemon", {})
        .get("lease", {})
        .get("idle_timeout", 60.0),
        "lease_heartbeat_timeout": ctx.settings.get("daemon", {})
        .get("lease", {})
        .get("heartbeat_timeout", 1.5),
        "joints": [
            {
                "id": j.id,
                "name": j.name,
                "urdf": j.urdf,
                "min": j.min_rad,
                "max": j.max_rad,
                "min_deg": j.min_deg,
                "max_deg": j.max_deg,
                "offset_deg": j.offset_deg,
                "direction": j.direction,
                "pid": [j.p, j.i, j.d],
            }
            for j in ctx.robot.joints
        ],
        "walking": ctx.settings.get("walking", {}),
        "imu": ctx.settings.get("imu", {}),
    }


def _table(ctx: MotionContext, dxl_id: int) -> tuple[type[MX28] | type[CM730], int]:
    if dxl_id == ctx.robot.cm730_id:
        return CM730, CM730_TABLE_SIZE
    if dxl_id in ctx.robot.by_id:
        return MX28, MX28_TABLE_SIZE
    raise Reject(
        ErrorCode.UNKNOWN,
        f"no device {dxl_id}: servos are {min(ctx.robot.ids)}..{max(ctx.robot.ids)}, "
        f"the CM-730 is {ctx.robot.cm730_id}",
        "id",
    )


def _hardware_writes(ctx: MotionContext) -> bool:
    return bool(
        ctx.extras.get("allow_hardware_writes")
        or ctx.settings.get("daemon", {}).get("allow_hardware_writes", False)
    )


@verb("registers")
def registers(req: Request, ctx: MotionContext) -> dict[str, Any]:
    dxl_id = F.integer(req.fields, "id", 0, 253)
    table, size = _table(ctx, dxl_id)
    address = F.integer(req.fields, "address", 0, size - 1)
    if req.op.name == "read":
        length = F.integer(req.fields, "length", 1, size - address, default=1)
        try:
            data = ctx.bus.read_registers(dxl_id, address, length)
        except BusError as exc:
            raise _bus_error(exc) from None
        return {"id": dxl_id, "address": address, "data": list(data)}
    data = req.fields["data"]
    if (
        not isinstance(data, list)
        or not data
        or any(isinstance(b, bool) or not isinstance(b, int) or not 0 <= b <= 255 for b in data)
    ):
        raise Reject(
            ErrorCode.INVALID, f"data must be a list of bytes 0..255, got {brief(data)}", "data"
        )
    end = address + len(data)
    if end > size:
        raise Reject(
            ErrorCode.OUT_OF_RANGE, f"{len(data)} bytes from {address} run past {size}", "data"
        )
    touched = [reg for reg in table if reg.reg.address < end and address < reg.reg.end]
    for reg in touched:
        r = reg.reg
        if r.access.value == "r":
            raise Reject(ErrorCode.REFUSED, f"{reg.name} ({r.address}) is read-only", "address")
        if is_protected(reg) and not _hardware_writes(ctx):
            raise Reject(
                ErrorCode.REFUSED,
                f"{reg.name} ({r.address}) can disable or lose the hardware: writes are refused "
                "unless the daemon runs with --allow-hardware-writes "
                "(config daemon.allow_hardware_writes)",
                "address",
            )
        if r.eeprom and not ctx.extras.get("allow_eeprom"):
            raise Reject(
                ErrorCode.REFUSED,
                f"{reg.name} ({r.address}) is EEPROM: writes are refused unless the daemon "
                "runs with --allow-eeprom",
                "address",
            )
    goal = MX28.GOAL_POSITION.reg.address
    if table is MX28 and address < goal + 2 and end > goal:
        _check_goal_write(ctx, dxl_id, address, bytes(data))
    id_reg = table.ID.reg
    new_id = data[id_reg.address - address] if address <= id_reg.address < end else dxl_id
    if new_id != dxl_id and (new_id in ctx.robot.by_id or new_id == ctx.robot.cm730_id):
        raise Reject(
            ErrorCode.REFUSED,
            f"ID {new_id} is already taken by another device on this bus: two devices with one "
            "ID answer over each other",
            "data",
        )
    return _write_and_verify(ctx, dxl_id, new_id, address, bytes(data))


def _write_and_verify(
    ctx: MotionContext, dxl_id: int, new_id: int, address: int, data: bytes
) -> dict[str, Any]:
    """Write, then read the bytes back (at the new ID after an ID change) and report what the
    device holds: a lost status packet is not a failed write, and a write that did not take is
    not a success."""
    write_error: BusError | None = None
    try:
        ctx.bus.write_registers(dxl_id, address, data)
    except BusError as exc:
        write_error = exc  # the status may have come from the new ID, or been lost
    try:
        readback = ctx.bus.read_registers(new_id, address, len(data))
    except BusError as exc:
        if write_error is not None:
            raise _bus_error(write_error) from None
        raise Reject(
            ErrorCode.UNAVAILABLE,
            f"the write to device {dxl_id} was acknowledged but reading it back at ID {new_id} "
            f"failed: {exc} (see status.bus)",
        ) from None
    out: dict[str, Any] = {
        "id": new_id,
        "address": address,
        "data": list(data),
        "readback": list(readback),
        "verified": readback == data,
    }
    if new_id != dxl_id:
        out["moved_from"] = dxl_id
    if write_error is not None:
        out["status_lost"] = str(write_error)
    if readback != data:
        raise Reject(
            ErrorCode.UNAVAILABLE,
            f"device {new_id} holds {list(readback)} at {address} after writing {list(data)}: "
            "the write did not take (a locked or clamped register?)",
            "data",
        )
    return out


def _check_goal_write(ctx: MotionContext, dxl_id: int, address: int, data: bytes) -> None:
    """A raw goal write still has to respect the joint's configured limits."""
    goal = MX28.GOAL_POSITION.reg.address
    if not (address <= goal and goal + 1 < address + len(data)):
        raise Reject(
            ErrorCode.INVALID, "write both bytes of the goal position (30 and 31) at once", "data"
        )
    raw = data[goal - address] | (data[goal - address + 1] << 8)
    j = ctx.robot.by_id[dxl_id]
    F.joint_position(j, joint_angle(j, raw), "data")
