"""What the motion layer sees each tick and what a motion module is.

Angles are servo angles in rad after calibration (0 = raw 2048), indexed by joint id in arrays of
length ``N_SLOTS`` (index 0 unused) so ``frame.position[13]`` is the right knee.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from schemas.units import GRAVITY, IMU_CENTER

if TYPE_CHECKING:
    from robot_daemon.motion.manager import MotionManager

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


@dataclass
class Targets:
    """What the motion layer wants written this tick."""

    goal: dict[int, float] = field(default_factory=dict)  # joint id → rad
    gains: dict[int, tuple[int, int, int]] = field(default_factory=dict)  # id → (p, i, d)


class MotionModule:
    """Base of every motion module. Subclasses override ``step`` and the lifecycle hooks.

    A module only ever gets to write the joints the manager says it owns; it takes joints with
    ``self.claim(ids)`` and gives them back with ``self.release(ids)``.
    """

    name: str = "module"

    def __init__(self) -> None:
        self.manager: MotionManager | None = None

    # -- called by the manager -----------------------------------------------------------
    def attach(self, manager: MotionManager) -> None:
        self.manager = manager

    def step(self, frame: JointFrame) -> dict[int, float]:
        """Goals (rad) for some of the joints this module owns. Called every tick."""
        return {}

    def observe(self, frame: JointFrame) -> None:
        """Called every tick for every module, owning joints or not, before any ``step``:
        for modules that watch (fall detection) or sequence others (choreography)."""

    def gains(self) -> dict[int, tuple[int, int, int]]:
        """Gains for owned joints that differ from the config defaults."""
        return {}

    def on_released(self, ids: set[int]) -> None:
        """Another module took these joints (or they were released): forget them."""

    def stop(self) -> None:
        """Stop gracefully (finish the step, brake to a stable pose)."""

    def halt(self) -> None:
        """Stop now; the manager will hold the present pose."""

    @property
    def active(self) -> bool:
        return bool(self.owned())

    def status(self) -> dict[str, Any]:
        return {"active": self.active}

    # -- helpers for subclasses ------------------------------------------------------------
    def owned(self) -> set[int]:
        return self.manager.owned_by(self.name) if self.manager else set()

    def claim(self, ids: set[int] | list[int] | tuple[int, ...]) -> None:
        assert self.manager is not None, f"{self.name} is not attached to a manager"
        self.manager.claim(self.name, set(ids))

    def release(self, ids: set[int] | list[int] | tuple[int, ...] | None = None) -> None:
        if self.manager is not None:
            self.manager.release(self.name, set(ids) if ids is not None else None)

    def emit(self, kind: str, message: str, **data: Any) -> None:
        if self.manager is not None:
            self.manager.emit(kind, message, **data)
