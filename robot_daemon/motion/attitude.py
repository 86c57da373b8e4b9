"""Gravity in the body frame from the CM-730's gyro and accelerometer: a complementary filter.

The gyro turns the estimate (a world-fixed vector seen from a body turning at ω changes as
dg/dt = −ω × g); the accelerometer pulls it toward −accel/|accel| with time constant ``tau``,
only while |accel| is within ``accel_band`` of 1 g (a shove or a landing is not gravity). This is
the gravity-only part of a Mahony filter: the policy contract needs the direction of gravity,
not yaw, so three floats are the whole state. Plain floats, not numpy: on 3-vectors numpy's
per-call overhead is most of the cost (``benchmarks/learn_benchmark.py`` measures the tick cost).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from schemas.units import GRAVITY

Vector = Sequence[float] | np.ndarray  # three components, body frame


class GravityFilter:
    def __init__(self, tau: float = 0.5, accel_band: float = 0.3) -> None:
        self.tau = tau
        self.accel_band = accel_band
        self.g = [0.0, 0.0, -1.0]  # unit gravity direction, body frame; upright
        self._started = False

    def reset(self, accel: Vector | None = None) -> None:
        self._started = False
        self.g = [0.0, 0.0, -1.0]
        if accel is not None:
            self.update((0.0, 0.0, 0.0), accel, 0.0)

    def set(self, g: Vector) -> None:
        """Start from a known gravity direction (a simulator's true attitude)."""
        n = math.sqrt(sum(float(v) ** 2 for v in g)) or 1.0
        self.g = [float(v) / n for v in g]
        self._started = True

    def update(self, gyro: Vector, accel: Vector, dt: float) -> list[float]:
        gx, gy, gz = self.g
        wx, wy, wz = float(gyro[0]), float(gyro[1]), float(gyro[2])
        # g ← g − dt (ω × g)
        gx, gy, gz = (
            gx - dt * (wy * gz - wz * gy),
            gy - dt * (wz * gx - wx * gz),
            gz - dt * (wx * gy - wy * gx),
        )
        ax, ay, az = float(accel[0]), float(accel[1]), float(accel[2])
        norm_a = math.sqrt(ax * ax + ay * ay + az * az)
        if norm_a > 1e-6:
            if not self._started:
                k = 1.0  # the first sample: trust the accelerometer at once
            elif abs(norm_a / GRAVITY - 1.0) <= self.accel_band:
                k = dt / (self.tau + dt) if self.tau > 0 else 1.0
            else:
                k = 0.0
            gx += k * (-ax / norm_a - gx)
            gy += k * (-ay / norm_a - gy)
            gz += k * (-az / norm_a - gz)
            self._started = True
        n = math.sqrt(gx * gx + gy * gy + gz * gz) or 1.0
        self.g = [gx / n, gy / n, gz / n]
        return self.g

    @property
    def upright(self) -> float:
        """−g_z: 1 upright, 0 lying, −1 upside down (the fall termination compares it)."""
        return -self.g[2]
