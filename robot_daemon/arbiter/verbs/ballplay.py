"""The ``playball`` verb: start or stop ball play (find the ball, follow it, kick it).

``{"op": "start", "color": "red"}`` needs the lease and a camera (``--camera sim`` or a
device): it starts the ball play module and the finder's thread, which reads the frames of the
daemon's one camera owner (``ctx.camera``) while play runs. ``{"op": "stop"}`` is always
accepted. The phase is in ``status.motion.ball.phase`` and every change is a ``ballplay`` event.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from robot_daemon.arbiter import fields as F
from robot_daemon.arbiter.limp import refuse_limp
from robot_daemon.arbiter.registry import MotionContext, Reject, Request, verb
from robot_daemon.motion.ball.module import BallPlayModule
from schemas.errors import ConfigError, ErrorCode
from schemas.extras import MissingExtraError

if TYPE_CHECKING:
    from robot_daemon.vision.ball_thread import BallVision

# The running finder thread lives with the module it feeds (one daemon, one module).
_VISION_ATTR = "_vision"


def _stop_vision(module: BallPlayModule) -> None:
    vision: BallVision | None = getattr(module, _VISION_ATTR, None)
    if vision is not None:
        vision.stop(timeout=0.0)  # never wait in the motion thread; it ends on its own
        setattr(module, _VISION_ATTR, None)


@verb("playball")
def playball(req: Request, ctx: MotionContext) -> dict[str, Any]:
    op = req.op.name
    module = ctx.module("ball", BallPlayModule, "ball play")
    if op == "stop":
        module.stop()
        _stop_vision(module)
        return {"op": "stop", "phase": module.phase}
    # The finder is loaded when play starts (~8 ms of CPU): every daemon registers this verb at
    # start, and most never play.
    from robot_daemon.vision.ball_finder import BallFinder, FinderSettings, color_names
    from robot_daemon.vision.ball_thread import BallVision

    ballplay = ctx.settings.get("ballplay", {})
    color = F.text(
        req.fields, "color", set(color_names(ballplay)), default=ballplay.get("color", "red")
    )
    try:
        finder = BallFinder(FinderSettings.from_config(ballplay, color))
    except ConfigError as exc:
        raise Reject(ErrorCode.INVALID, str(exc), "color") from None
    except MissingExtraError as exc:  # this robot's install has no OpenCV
        raise Reject(ErrorCode.UNAVAILABLE, str(exc)) from None
    camera = ctx.camera
    if camera is None:
        raise Reject(
            ErrorCode.UNAVAILABLE,
            "ball play needs a camera: start the daemon with --camera sim (simulator) or "
            "--camera 0 (the robot's webcam)",
        )
    # It walks, turns the head and kicks (a page on the whole body): every joint takes part.
    refuse_limp(ctx, ctx.robot.ids, "ball play")
    _stop_vision(module)
    module.start(color)
    publish = ctx.publish
    vision = BallVision(
        camera.consumer,
        finder,
        module,
        (lambda det: publish("vision_ball", det)) if publish is not None else None,
        hz=module.settings.vision_hz,
    ).start()
    setattr(module, _VISION_ATTR, vision)
    return {"op": "start", "color": color, "phase": module.phase, "camera": camera.spec}
