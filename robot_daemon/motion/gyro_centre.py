"""Gyro centre calibration at start: the robot must be still, and nothing that uses the gyro
runs until it is measured.

As ROBOTIS's ``MotionManager::Process`` (DARwIn-OP framework, ``Framework/src/MotionManager.cpp``):
100 error-free CM-730 samples of gyro X and Y; when the standard deviation of each is below 2
counts, their means are the centres (``m_FBGyroCenter``, ``m_RLGyroCenter``) and
``m_CalibrationStatus`` becomes 1; the framework computes falls and runs its modules only then.
Where ROBOTIS gives up (status −1, centres 512) and leaves the retry to its caller, this module
starts over, so a robot picked up during the first second calibrates once it is put down.

The module drives no joint. It runs first each tick and writes what it knows onto the frame
(``frame.imu_calibrated``, ``frame.gyro_centre``) for the fall monitor and the walking balance;
``status.motion.imu`` publishes the centres.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from config.loader import section_to
from robot_daemon.frames import JointFrame
from robot_daemon.motion.interface import MotionModule
from schemas.units import IMU_CENTER


@dataclass(frozen=True)
class GyroCalibrationSettings:
    """``[imu.calibration]`` (config/daemon.toml)."""

    samples: int = 100  # MotionManager.cpp GYRO_WINDOW_SIZE
    max_sd: float = 2.0  # MotionManager.cpp MARGIN_OF_SD (counts)


class GyroCalibration(MotionModule):
    name = "imu"

    def __init__(self, settings: dict[str, Any] | None = None) -> None:
        super().__init__()
        cfg = section_to(GyroCalibrationSettings, settings or {}, "imu.calibration")
        self.samples = max(2, cfg.samples)
        self.max_sd = cfg.max_sd
        self._buf = np.zeros((self.samples, 3))
        self._n = 0
        self.centre = np.full(3, float(IMU_CENTER))
        self.calibrated = False
        self.attempts = 0

    def observe(self, frame: JointFrame) -> None:
        if not self.calibrated and frame.imu_valid:
            self._buf[self._n] = frame.gyro_raw
            self._n += 1
            if self._n == self.samples:
                self._finish()
        frame.imu_calibrated = self.calibrated
        frame.gyro_centre = self.centre

    def _finish(self) -> None:
        self._n = 0
        self.attempts += 1
        sd = self._buf.std(axis=0)
        if bool(np.all(sd < self.max_sd)):
            self.centre = np.floor(self._buf.mean(axis=0))  # the framework truncates to int
            self.calibrated = True
            self.emit(
                "imu",
                "gyro calibrated: centre "
                + " ".join(f"{a}={c:.0f}" for a, c in zip("xyz", self.centre, strict=True)),
                calibrated=True,
                gyro_centre=[float(c) for c in self.centre],
            )
        elif self.attempts == 1:
            self.emit(
                "imu",
                f"gyro calibration: the robot moved (SD {max(sd):.1f} counts, needs < "
                f"{self.max_sd:g}); keep it still, calibrating again",
                calibrated=False,
                gyro_centre=None,
            )

    def recalibrate(self) -> None:
        """Measure the centres again (the CM-730 was reset: DXL power came back)."""
        self.calibrated = False
        self._n = 0

    def status(self) -> dict[str, Any]:
        return {
            "active": False,
            "calibrated": self.calibrated,
            "gyro_centre": [float(c) for c in self.centre],
            "attempts": self.attempts,
        }
