"""What the bus hands the motion layer each tick and what it takes back: the frame of sensor
state and the targets to write.

Below both the bus (which builds frames and writes targets) and the motion modules (which read
frames and return targets), so neither imports the other.

Angles are servo angles in rad after calibration (0 = raw 2048), indexed by joint id in arrays of
length ``N_SLOTS`` (index 0 unused) so ``frame.position[13]`` is the right knee.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from schemas.units import GRAVITY, IMU_CENTER

N_SLOTS = 21  # ids 1..20, slot 0 unused


def empty_slots(fill: float = 0.0) -> np.ndarray:
    return np.full(N_SLOTS, fill, dtype=float)


@dataclass
class JointFrame:
    """Sensor state at the start of a tick."""

    tick: int
    time: float  # s, the loop's clock (monotonic, or simulated)
    dt: float  # s, time since the previous tick (the period when ticks are on time; bounded)
    position: np.ndarray = field(default_factory=empty_slots)  # rad
    velocity: np.ndarray = field(default_factory=empty_slots)  # rad/s
    load: np.ndarray = field(default_factory=empty_slots)  # fraction of max torque
    online: np.ndarray = field(default_factory=lambda: np.zeros(N_SLOTS, dtype=bool))
    torque_enabled: np.ndarray = field(default_factory=lambda: np.zeros(N_SLOTS, dtype=bool))
    gyro: np.ndarray = field(default_factory=lambda: np.zeros(3))  # rad/s, x y z (robot axes)
    accel: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, GRAVITY]))  # m/s²
    gyro_raw: np.ndarray = field(default_factory=lambda: np.full(3, IMU_CENTER))  # counts x y z
    accel_raw: np.ndarray = field(default_factory=lambda: np.full(3, IMU_CENTER))  # counts x y z
    # The CM-730 answered this tick's bulk read without error bits: the IMU fields are its
    # reading (False before it first answered, and on a tick it missed: the fields are stale).
    imu_valid: bool = True
    # Gyro counts at rest, measured at start (motion/gyro_centre.py); the balance and the
    # published rates are relative to it.
    gyro_centre: np.ndarray = field(default_factory=lambda: np.full(3, float(IMU_CENTER)))
    imu_calibrated: bool = True  # set each tick by the gyro calibration module
    # The goal each servo holds (last written, or read from it at start), raw, and the bus's
    # raw → joint angle conversion: converted only when a motion starts (start_of), not per
    # tick. None in synthetic frames: a motion then starts from the present position.
    goal_raw: np.ndarray | None = None
    to_joint: Callable[[int, float], float] | None = None

    def start_of(self, joint_id: int) -> float:
        """Where a new motion of a joint starts: the goal it holds while torqued, as ROBOTIS's
        Action.cpp starts a step from the joint's last value (``m_Joint.GetValue``), not from
        where it sags to under load (a loaded joint stands below its goal; starting there made
        it drop by the sag first); the present position when it has no torque or no goal."""
        raw, convert = self.goal_raw, self.to_joint
        if raw is not None and convert is not None and self.torque_enabled[joint_id]:
            return convert(joint_id, float(raw[joint_id]))
        return float(self.position[joint_id])


@dataclass
class Targets:
    """What the motion layer wants written this tick."""

    goal: dict[int, float] = field(default_factory=dict)  # joint id → rad
    gains: dict[int, tuple[int, int, int]] = field(default_factory=dict)  # id → (p, i, d)
