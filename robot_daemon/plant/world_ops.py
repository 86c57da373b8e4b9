"""World ops on the simulator's control interface (``Keys(robot).sim_control``).

| op | fields | does |
|---|---|---|
| `get_world` | | the World message as a map (robot x/y/yaw, ball, fallen, sim_time) |
| `place_robot` | `x`, `y` (m), `yaw` (rad, default 0) | stands the robot there (clears a fall) |
| `place_ball` | `x`, `y` (m), `vx`, `vy` (m/s, default 0) | puts the ball there |
| `remove_ball` | | takes the ball off the field |
| `push` | `fx`, `fy`, `fz` (N, field; fz default 0), `duration` (s, default 0.1) | a shove |
| `render` | `format` (`bgr`, `jpeg`), `quality` (1-100, 80) | one camera frame (below) |

`render` answers ``width``, ``height``, ``seq`` and either ``bgr`` (raw bytes, row-major) or, with
``format="jpeg"``, ``jpeg`` (the bytes of a JPEG file at ``quality``).

`push`: the MuJoCo plant applies the force at the torso's centre of mass for ``duration`` s of
simulated time; the kinematic body tips over the way it was pushed when the horizontal impulse
reaches ``[world.falls] push_fall_impulse``. Forces within ±200 N, duration within (0, 1] s.

The ops find the world through the emulator (``emulator.world``, set by :func:`install`), so
they answer "no world" clearly on an emulator started with ``--no-world``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from robot_daemon.emulator.op_table import field, register_control_op
from robot_daemon.vision.opencv import encode_jpeg
from schemas.errors import FieldError, brief

if TYPE_CHECKING:
    from robot_daemon.emulator.emulator import Emulator
    from robot_daemon.plant.world import SimWorld

RENDER_FORMATS = ("bgr", "jpeg")
# Anything placed farther than this from the field centre is a typo, not a test (m).
MAX_COORD = 50.0


def world_of(emulator: Emulator) -> SimWorld:
    world = getattr(emulator, "world", None)
    if world is None:
        raise ValueError("this emulator runs without a world (started with --no-world)")
    return world


def _coord(request: dict[str, Any], name: str, default: Any = ...) -> float:
    value = field(request, name, float) if default is ... else field(request, name, float, default)
    if not math.isfinite(value) or abs(value) > MAX_COORD:
        raise FieldError(name, f"{name}={brief(value)} must be finite and within ±{MAX_COORD} m")
    return value


def get_world(emulator: Emulator, request: dict[str, Any]) -> dict[str, Any]:
    return world_of(emulator).snapshot().to_dict()


def place_robot(emulator: Emulator, request: dict[str, Any]) -> dict[str, Any]:
    x, y = _coord(request, "x"), _coord(request, "y")
    yaw = field(request, "yaw", float, 0.0)
    if not math.isfinite(yaw):
        raise FieldError("yaw", f"yaw={brief(yaw)} must be finite (rad)")
    world = world_of(emulator)
    world.place_robot(x, y, math.remainder(yaw, 2 * math.pi))
    return {"robot": world.snapshot().robot}


def place_ball(emulator: Emulator, request: dict[str, Any]) -> dict[str, Any]:
    x, y = _coord(request, "x"), _coord(request, "y")
    vx, vy = _coord(request, "vx", 0.0), _coord(request, "vy", 0.0)
    world = world_of(emulator)
    world.place_ball(x, y, vx, vy)
    return {"ball": world.snapshot().ball}


def remove_ball(emulator: Emulator, request: dict[str, Any]) -> dict[str, Any]:
    world_of(emulator).remove_ball()
    return {"ball": {"present": False}}


# A push is a shove by hand, not a cannon (N, s).
MAX_PUSH_N = 200.0
MAX_PUSH_S = 1.0


def push(emulator: Emulator, request: dict[str, Any]) -> dict[str, Any]:
    force = []
    for name in ("fx", "fy", "fz"):
        value = field(request, name, float) if name != "fz" else field(request, name, float, 0.0)
        if not math.isfinite(value) or abs(value) > MAX_PUSH_N:
            raise FieldError(
                name, f"{name}={brief(value)} must be finite and within ±{MAX_PUSH_N} N"
            )
        force.append(value)
    duration = field(request, "duration", float, 0.1)
    if not math.isfinite(duration) or not 0.0 < duration <= MAX_PUSH_S:
        raise FieldError("duration", f"duration={brief(duration)} must be in (0, {MAX_PUSH_S}] s")
    world = world_of(emulator)
    world.push((force[0], force[1], force[2]), duration)
    return {"impulse": [f * duration for f in force], "fallen": world.snapshot().fallen}


def render(emulator: Emulator, request: dict[str, Any]) -> dict[str, Any]:
    """One frame, raw or as the JPEG a UVC camera in MJPEG would send: the simulator (a laptop)
    encodes, so the daemon's camera passes the bytes through as it does a real camera's."""
    fmt = field(request, "format", str, "bgr")
    if fmt not in RENDER_FORMATS:
        raise FieldError(
            "format", f"format={brief(fmt)} must be one of {', '.join(RENDER_FORMATS)}"
        )
    quality = field(request, "quality", int, 80)
    if not 1 <= quality <= 100:
        raise FieldError("quality", f"quality={brief(quality)} must be within 1..100")
    world = world_of(emulator)
    img = world.render()
    world.frames_rendered += 1
    h, w = img.shape[:2]
    reply: dict[str, Any] = {"width": w, "height": h, "seq": world.frames_rendered}
    if fmt == "jpeg":
        reply["jpeg"] = encode_jpeg(img, quality)
    else:
        reply["bgr"] = img.tobytes()
    return reply


def install() -> None:
    """Add the world ops to the emulator's control table."""
    for name, fn in (
        ("get_world", get_world),
        ("place_robot", place_robot),
        ("place_ball", place_ball),
        ("remove_ball", remove_ball),
        ("push", push),
        ("render", render),
    ):
        register_control_op(name, fn)
