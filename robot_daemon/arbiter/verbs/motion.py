"""Motion verbs: action, walk, walk_params, head, choreography, sound, behaviours.

Walk commands are SI: x, y in m/s, turn in rad/s. With the gait period T (s, ``period_time``):
X [mm per step] = x·T·1000/4 (the body advances 2·X per step), Y [mm] = y·T·1000/2,
A [° per step] = degrees(turn·T/2). A speed beyond the configured ``max_x``/``max_y``/
``max_turn`` is refused, never clamped.
"""

from __future__ import annotations

import math
from typing import Any

from robot_daemon.arbiter import fields as F
from robot_daemon.arbiter.limp import refuse_limp
from robot_daemon.arbiter.registry import MotionContext, Reject, Request, verb
from robot_daemon.motion.action.player import ActionModule, page_joints
from robot_daemon.motion.behaviours import BehaviourError, Item
from robot_daemon.motion.choreography import ChoreographyModule
from robot_daemon.motion.head import HeadModule
from robot_daemon.motion.walking.gait import WALK_IDS, WalkingModule, si_from_amplitudes
from robot_daemon.motion.walking.ready import HEAD_IDS
from schemas.errors import ErrorCode

MAX_ITEMS = 256


def _behaviour_error(exc: BehaviourError, prefix: str = "") -> Reject:
    code = ErrorCode.UNKNOWN if "no " in str(exc)[:4] else ErrorCode.INVALID
    return Reject(code, f"{prefix}{exc}", exc.field)


# -- action ------------------------------------------------------------------------------------
@verb("action")
def action(req: Request, ctx: MotionContext) -> dict[str, Any]:
    player: ActionModule = ctx.module("action", ActionModule)
    op = req.op.name
    if op == "stop":
        player.stop()
        return {"op": op, "playing": player.playing}
    if op == "brake":
        player.brake()
        return {"op": op, "playing": player.playing}
    say = None
    if req.fields.get("behaviour") is not None:
        choreo: ChoreographyModule = ctx.module("choreography", ChoreographyModule)
        try:
            b = choreo.behaviours.get(req.fields["behaviour"])
        except BehaviourError as exc:
            raise _behaviour_error(exc) from None
        if b.kind != "action":
            raise Reject(
                ErrorCode.INVALID,
                f"behaviour {b.id} ({b.name}) is a {b.kind}; play it with `choreography`",
                "behaviour",
            )
        ref: int | str = b.params["page"]
        say = b.params.get("say")
        field = "behaviour"
    elif req.fields.get("page") is not None:
        ref, field = F.integer(req.fields, "page", 1, 255), "page"
    elif req.fields.get("name") is not None:
        ref, field = F.text(req.fields, "name"), "name"
    else:
        raise Reject(ErrorCode.INVALID, "play needs a page, a name or a behaviour", "page")
    try:
        refuse_limp(ctx, _page_joints(player, ref), f"page {ref}", field)
        page = player.play(ref)
    except KeyError as exc:
        raise Reject(ErrorCode.UNKNOWN, str(exc.args[0]), field) from None
    except ValueError as exc:
        raise Reject(ErrorCode.OUT_OF_RANGE, str(exc), field) from None
    applied: dict[str, Any] = {
        "op": op,
        "page": page.number,
        "name": page.name,
        "steps": len(page.steps),
        "next": page.next,
    }
    if say:
        choreo = ctx.module("choreography", ChoreographyModule)
        applied["sound"] = choreo.sound.play(ctx.emit, say=say)
    return applied


def _page_joints(player: ActionModule, ref: int | str) -> set[int]:
    """Every joint a page drives, and the pages it chains to (``KeyError``: no such page)."""
    lib = player.library
    return {j for n in lib.chain(lib.page(ref).number) for j in page_joints(lib.pages[n])}


# -- walking -----------------------------------------------------------------------------------
def _speed_limits(walking: WalkingModule) -> tuple[float, float, float]:
    p = walking.params
    return si_from_amplitudes(p.max_x, p.max_y, p.max_turn, p.period_time)


@verb("walk")
def walk(req: Request, ctx: MotionContext) -> dict[str, Any]:
    walking: WalkingModule = ctx.module("walking", WalkingModule)
    op = req.op.name
    if op == "stop":
        walking.stop()
        # steps: step boundaries so far; the `walk` "stopped" event carries the count at the end
        return {
            "op": op,
            "walking": walking.running,
            "stopping": walking.running,
            "steps": walking.steps,
        }
    xm, ym, tm = _speed_limits(walking)
    x = F.number(req.fields, "x", -xm, xm, default=0.0)
    y = F.number(req.fields, "y", -ym, ym, default=0.0)
    turn = F.number(req.fields, "turn", -tm, tm, default=0.0)
    if op == "start":
        refuse_limp(ctx, WALK_IDS, "walk")
        amp = walking.start(x, y, turn)
    else:
        amp = walking.set_speed(x, y, turn)
    return {
        "op": op,
        "x": x,
        "y": y,
        "turn": turn,
        "amplitude": {"x_mm": amp[0], "y_mm": amp[1], "turn_deg": amp[2]},
        "walking": walking.running,
    }


@verb("walk_params")
def walk_params(req: Request, ctx: MotionContext) -> dict[str, Any]:
    walking: WalkingModule = ctx.module("walking", WalkingModule)
    changes = req.fields.get("set")
    changed: dict[str, Any] = {}
    if req.op.name == "set":
        if not isinstance(changes, dict) or not changes:
            raise Reject(ErrorCode.INVALID, "set must be a map {name: value}", "set")
        try:
            changed = walking.params.update(changes)
        except ValueError as exc:
            name = next((k for k in changes if f" {k}" in str(exc)), None)
            raise Reject(
                ErrorCode.OUT_OF_RANGE, str(exc), f"set.{name}" if name else "set"
            ) from None
    xm, ym, tm = _speed_limits(walking)
    return {
        "params": walking.params.to_dict(),
        "changed": changed,
        "max_speed": {"x": xm, "y": ym, "turn": tm},
    }


# -- head --------------------------------------------------------------------------------------
@verb("head")
def head(req: Request, ctx: MotionContext) -> dict[str, Any]:
    module: HeadModule = ctx.module("head", HeadModule)
    f = req.fields
    try:
        if req.op.name == "home":
            pan, tilt = module.home()
            mode = "home"
        elif req.op.name == "track":
            track = f["track"]
            if not isinstance(track, dict):
                raise Reject(ErrorCode.INVALID, "track must be {pan_error, tilt_error}", "track")
            pe = F.number(track, "pan_error", -math.pi, math.pi, default=0.0)
            te = F.number(track, "tilt_error", -math.pi, math.pi, default=0.0)
            pan, tilt = module.track(pe, te)
            mode = "track"
        else:
            pan = F.number(f, "pan", default=module.target[0] if module.target else 0.0)
            tilt = F.number(f, "tilt", default=module.target[1] if module.target else 0.0)
            if f.get("pan") is None and f.get("tilt") is None:
                raise Reject(ErrorCode.INVALID, "head needs pan/tilt, track or op=home", "pan")
            pan, tilt = module.move(pan, tilt)
            mode = "move"
    except ValueError as exc:
        field = "tilt" if str(exc).startswith("tilt") else "pan"
        raise Reject(ErrorCode.OUT_OF_RANGE, f"head {exc}", field) from None
    return {"mode": mode, "pan": pan, "tilt": tilt}


# -- choreography, sound, behaviours ---------------------------------------------------------------
def _expand_legacy(items: list[Any], choreo: ChoreographyModule) -> list[Any]:
    """Legacy orchestrate items: {"page": P, "type": T} and {"time": S} (the duration of the
    most recent walk before it, or a forward walk of S seconds)."""
    out: list[Any] = []
    for i, raw in enumerate(items):
        if isinstance(raw, dict) and "type" in raw:
            t = F.integer(raw, "type", 0, 255)
            p = F.integer(raw, "page", 0, 100000)
            try:
                out.append(choreo.behaviours.legacy_item(p, t))
            except BehaviourError as exc:
                raise _behaviour_error(exc, f"item {i + 1}: ") from None
        elif isinstance(raw, dict) and set(raw) == {"time"}:
            seconds = F.number(raw, "time", 0.0, 600.0)
            last = out[-1] if out else None
            if isinstance(last, dict) and _is_walk(last, choreo) and "duration" not in last:
                last["duration"] = seconds
            else:
                out.append({"behaviour": 100, "duration": seconds})
        else:
            out.append(raw)
    return out


def _is_walk(item: dict[str, Any], choreo: ChoreographyModule) -> bool:
    if item.get("kind") == "walk":
        return True
    try:
        return "behaviour" in item and choreo.behaviours.get(item["behaviour"]).kind == "walk"
    except BehaviourError:
        return False


@verb("choreography")
def choreography(req: Request, ctx: MotionContext) -> dict[str, Any]:
    choreo: ChoreographyModule = ctx.module("choreography", ChoreographyModule)
    op = req.op.name
    if op == "stop":
        was = choreo.playing
        choreo.stop()
        return {"op": op, "was_playing": was, "run": choreo.run}
    raw = req.fields.get("items")
    if not isinstance(raw, list) or not raw:
        raise Reject(ErrorCode.INVALID, "items must be a non-empty list", "items")
    if len(raw) > MAX_ITEMS:
        raise Reject(ErrorCode.OUT_OF_RANGE, f"at most {MAX_ITEMS} items", "items")
    lang = F.text(req.fields, "lang", {"en", "pt"}, default="en")
    player: ActionModule = ctx.module("action", ActionModule)
    walking: WalkingModule = ctx.module("walking", WalkingModule)
    head_mod: HeadModule = ctx.module("head", HeadModule)
    xm, ym, tm = _speed_limits(walking)
    items: list[Item] = []
    for i, r in enumerate(_expand_legacy(raw, choreo)):
        where = f"item {i + 1}: "
        try:
            item = choreo.behaviours.resolve(r, player.library, lang)
        except BehaviourError as exc:
            raise _behaviour_error(exc, where) from None
        p = item.params
        if item.kind == "walk":
            if p.get("duration") is None:
                raise Reject(ErrorCode.INVALID, f"{where}a walk needs a duration (s)", "duration")
            for axis, lim in (("x", xm), ("y", ym), ("turn", tm)):
                if abs(p[axis]) > lim:
                    raise Reject(
                        ErrorCode.OUT_OF_RANGE,
                        f"{where}{axis}={p[axis]} is beyond ±{lim:.3f}",
                        axis,
                    )
        elif item.kind == "head":
            try:
                head_mod.check(p["pan"], p["tilt"])
            except ValueError as exc:
                raise Reject(ErrorCode.OUT_OF_RANGE, f"{where}head {exc}", "pan") from None
        elif item.kind == "action":
            bad = player.library.violations(ctx.robot, player.library.chain(p["page"]))
            if bad:
                raise Reject(ErrorCode.OUT_OF_RANGE, f"{where}{bad[0]}", "page")
        driven: set[int] = set({"walk": WALK_IDS, "head": HEAD_IDS}.get(item.kind, ()))
        if item.kind == "action":
            driven = _page_joints(player, p["page"])
        refuse_limp(ctx, driven, f"choreography {where}{item.kind}", "items")
        items.append(item)
    choreo.led_writer = lambda head_word, eye_word: ctx.bus.set_leds(head_word, eye_word, None)
    run = choreo.play(items)
    return {"op": op, "run": run, "items": [i.to_dict() for i in items]}


@verb("sound")
def sound(req: Request, ctx: MotionContext) -> dict[str, Any]:
    choreo: ChoreographyModule = ctx.module("choreography", ChoreographyModule)
    file = F.optional_text(req.fields, "file")
    say = F.optional_text(req.fields, "say")
    lang = F.optional_text(req.fields, "lang", {"en", "pt"})
    if not file and not say:
        raise Reject(ErrorCode.INVALID, "sound needs a file or a phrase (say)", "say")
    if say is not None and len(say) > 500:
        raise Reject(ErrorCode.OUT_OF_RANGE, "say is longer than 500 characters", "say")
    try:
        return choreo.sound.play(ctx.emit, file=file, say=say, lang=lang)
    except ValueError as exc:
        raise Reject(ErrorCode.UNAVAILABLE, str(exc), "file" if file else "say") from None


@verb("behaviours")
def behaviours(req: Request, ctx: MotionContext) -> dict[str, Any]:
    choreo: ChoreographyModule = ctx.module("choreography", ChoreographyModule)
    player: ActionModule = ctx.module("action", ActionModule)
    return {**choreo.behaviours.listing(), "pages": player.library.listing()}
