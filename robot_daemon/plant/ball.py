"""The ball: rolls with friction, and is pushed when a sole sweeps through it.

A foot is a box (the sole's length and width, ``feet.height`` tall) at the sole's pose. When the
ball's centre comes within a radius of it, the ball is pushed out along the contact normal and
takes at least (1 + restitution) × the foot's speed along that normal (a light ball hit by a
heavy foot), so a slow step nudges it and a kick sends it away.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_daemon.plant.world_settings import BallSettings, FeetSettings


@dataclass
class BallState:
    """Where the simulated ball is on the field and how fast it rolls (m, m/s)."""

    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0

    @property
    def speed(self) -> float:
        return math.hypot(self.vx, self.vy)


class Ball:
    def __init__(self, settings: BallSettings, feet: FeetSettings) -> None:
        self.settings = settings
        self.feet = feet
        self.state: BallState | None = None
        self.touches = 0  # contacts with a foot that pushed the ball

    def place(self, x: float, y: float, vx: float = 0.0, vy: float = 0.0) -> None:
        self.state = BallState(float(x), float(y), float(vx), float(vy))

    def remove(self) -> None:
        self.state = None

    def step(self, dt: float, soles: list[tuple[np.ndarray, np.ndarray]]) -> None:
        """Advance by ``dt``; ``soles`` are (pose 4×4 in the field, velocity m/s) per foot."""
        b = self.state
        if b is None or dt <= 0:
            return
        s = self.settings
        b.x += b.vx * dt
        b.y += b.vy * dt
        speed = b.speed
        if speed > 0:
            slower = max(0.0, speed - s.rolling_decel * dt)
            if slower < s.rest_speed:
                slower = 0.0
            b.vx *= slower / speed
            b.vy *= slower / speed
        for pose, velocity in soles:
            self._collide(b, pose, velocity)

    def _collide(self, b: BallState, pose: np.ndarray, velocity: np.ndarray) -> None:
        s, f = self.settings, self.feet
        r = s.radius
        # The ball's centre in the sole's frame (box from z=0 to the foot's height).
        inv_rot = pose[:3, :3].T
        c = inv_rot @ (np.array([b.x, b.y, r]) - pose[:3, 3])
        closest = np.array(
            [
                min(max(c[0], -f.length / 2), f.length / 2),
                min(max(c[1], -f.width / 2), f.width / 2),
                min(max(c[2], 0.0), f.height),
            ]
        )
        gap = c - closest
        dist = float(np.linalg.norm(gap))
        if dist >= r:
            return
        if dist > 1e-9:
            normal = pose[:3, :3] @ (gap / dist)
        else:  # the centre is inside the foot: push it out the way the foot moves
            normal = velocity / max(1e-9, float(np.linalg.norm(velocity)))
        n2 = np.array([normal[0], normal[1]])
        norm = float(np.hypot(*n2))
        if norm < 1e-6:
            return  # a foot straight above or below the ball does not push it sideways
        n2 /= norm
        depth = r - dist
        b.x += n2[0] * depth
        b.y += n2[1] * depth
        foot_speed = float(velocity[0] * n2[0] + velocity[1] * n2[1])
        ball_speed = b.vx * n2[0] + b.vy * n2[1]
        target = (1.0 + s.restitution) * foot_speed
        if target > ball_speed:
            b.vx += (target - ball_speed) * n2[0]
            b.vy += (target - ball_speed) * n2[1]
            self.touches += 1
