"""The ``playball`` verb: start or stop ball play (find the ball, follow it, kick it).

``{"op": "start", "color": "red"}`` needs the lease and a camera (``--camera sim`` or a
device): it starts the ball play module and the finder's thread, which reads its own frames
from the daemon's camera source while play runs. ``{"op": "stop"}`` is always accepted. The
phase is in ``status.motion.ball.phase`` and every change is a ``ballplay`` event.
"""

from __future__ import annotations

from typing import Any

import zenoh

from robot_daemon.arbiter import fields as F
from robot_daemon.arbiter.registry import MotionContext, Reject, Request, verb
from robot_daemon.motion.ball.module import BallPlayModule
from robot_daemon.vision.ball_finder import BallFinder, FinderSettings, color_names
from robot_daemon.vision.ball_thread import BallVision
from schemas.errors import CameraError, ConfigError, ErrorCode
from schemas.messages import BallDetection, encode

# The running finder thread lives with the module it feeds (one daemon, one module).
_VISION_ATTR = "_vision"


def _module(ctx: MotionContext) -> BallPlayModule:
    module = ctx.manager.get("ball")
    if not isinstance(module, BallPlayModule):
        raise Reject(ErrorCode.UNAVAILABLE, "ball play is not part of this daemon's motion setup")
    return module


def _stop_vision(module: BallPlayModule) -> None:
    vision: BallVision | None = getattr(module, _VISION_ATTR, None)
    if vision is not None:
        vision.stop(timeout=0.0)  # never wait in the motion thread; it ends on its own
        setattr(module, _VISION_ATTR, None)


@verb("playball")
def playball(req: Request, ctx: MotionContext) -> dict[str, Any]:
    op = F.text(req.fields, "op", {"start", "stop"})
    module = _module(ctx)
    if op == "stop":
        module.stop()
        _stop_vision(module)
        return {"op": "stop", "phase": module.phase}
    ballplay = ctx.settings.get("ballplay", {})
    color = F.text(
        req.fields, "color", set(color_names(ballplay)), default=ballplay.get("color", "red")
    )
    try:
        finder = BallFinder(FinderSettings.from_config(ballplay, color))
    except ConfigError as exc:
        raise Reject(ErrorCode.INVALID, str(exc), "color") from None
    daemon = ctx.extras.get("daemon")
    spec = getattr(getattr(daemon, "options", None), "camera", "none")
    if daemon is None or spec == "none":
        raise Reject(
            ErrorCode.UNAVAILABLE,
            "ball play needs a camera: start the daemon with --camera sim (simulator) or "
            "--camera 0 (the robot's webcam)",
        )
    _stop_vision(module)
    module.start(color)
    vision = BallVision(
        _source_opener(daemon, spec),
        finder,
        module,
        _publisher(daemon),
        hz=module.settings.vision_hz,
    ).start()
    setattr(module, _VISION_ATTR, vision)
    return {"op": "start", "color": color, "phase": module.phase, "camera": spec}


def _source_opener(daemon: Any, spec: str):
    from robot_daemon.vision.sources import SourceContext, open_source

    cam = daemon.settings.get("daemon", {}).get("camera", {})
    ctx = SourceContext(
        width=int(cam.get("width", 320)),
        height=int(cam.get("height", 240)),
        fps=float(cam.get("fps", 30)),
        session=daemon.session,
        robot=daemon.keys.robot,
        settings=daemon.settings,
    )

    def opener() -> Any:
        source = open_source(spec, ctx)
        if source is None:
            raise CameraError(f"camera {spec!r} gives no frames")
        return source

    return opener


def _publisher(daemon: Any):
    session, key = daemon.session, daemon.keys.vision_ball
    if session is None:
        return None

    def publish(det: BallDetection) -> None:
        session.put(key, encode(det), congestion_control=zenoh.CongestionControl.DROP)

    return publish
