"""World ops on the simulator's control interface (``Keys(robot).sim_control``).

| op | fields | does |
|---|---|---|
| `get_world` | | the World message as a map (robot x/y/yaw, ball, fallen, sim_time) |
| `place_robot` | `x`, `y` (m), `yaw` (rad, default 0) | stands the robot there (clears a fall) |
| `place_ball` | `x`, `y` (m), `vx`, `vy` (m/s, default 0) | puts the ball there |
| `remove_ball` | | takes the ball off the field |
| `render` | | one camera frame: `bgr` (raw bytes, row-major), `width`, `height`, `seq` |

The ops find the world through the emulator (``emulator.world``, set by :func:`install`), so
they answer "no world" clearly on an emulator started with ``--no-world``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from robot_daemon.sim.control import field, register_control_op
from schemas.errors import FieldError, brief

if TYPE_CHECKING:
    from robot_daemon.sim.emulator import Emulator
    from robot_daemon.sim.world.world import SimWorld

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


def render(emulator: Emulator, request: dict[str, Any]) -> dict[str, Any]:
    world = world_of(emulator)
    img = world.render()
    world.frames_rendered += 1
    h, w = img.shape[:2]
    return {"bgr": img.tobytes(), "width": w, "height": h, "seq": world.frames_rendered}


def install() -> None:
    """Add the world ops to the emulator's control table."""
    for name, fn in (
        ("get_world", get_world),
        ("place_robot", place_robot),
        ("place_ball", place_ball),
        ("remove_ball", remove_ball),
        ("render", render),
    ):
        register_control_op(name, fn)
