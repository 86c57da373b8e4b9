"""Where the simulated camera is, what it sees through and the field it looks at: what the
world's settings and a plant's pose name. Apart from the renderer so that a world nobody watches
(``darwin up --camera none``, most simulated robots) loads neither it nor the ball finder.

Camera frame: x along the optical axis, y to the left, z up (the robot's axes when the head looks
level). ``CameraPose.rotation`` maps camera axes to field axes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from config.loader import section_to
from robot_daemon.vision.camera_view import CameraView


@dataclass
class CameraPose:
    """Where the camera is on the field and which way it looks."""

    position: np.ndarray  # (3,) field frame, m
    rotation: np.ndarray  # (3, 3) camera axes → field axes


@dataclass(frozen=True)
class FieldGeometry:
    """The field's markings and goals (m), as the renderer draws them."""

    length: float = 9.0
    width: float = 6.0
    line_width: float = 0.05
    centre_circle_radius: float = 0.75
    goal_area_depth: float = 1.0
    goal_area_width: float = 3.0
    goal_width: float = 2.6
    goal_post_height: float = 0.8
    goal_post_radius: float = 0.05
    border: float = 1.5

    @classmethod
    def from_config(cls, field: dict[str, Any]) -> FieldGeometry:
        return section_to(cls, field, "world.field")


@dataclass(frozen=True)
class CameraModel(CameraView):
    """The robot's lens (the vision's :class:`CameraView`), with what rendering needs."""

    @property
    def fx(self) -> float:
        return (self.width / 2.0) / math.tan(math.radians(self.fov_h_deg) / 2.0)

    @property
    def fy(self) -> float:
        return (self.height / 2.0) / math.tan(math.radians(self.fov_v_deg) / 2.0)

    def rays(self) -> np.ndarray:
        """(h*w, 3) ray directions in the camera frame, row-major over the image."""
        v, u = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        d = np.stack(
            [
                np.ones_like(u),
                (self.width / 2.0 - (u + 0.5)) / self.fx,
                (self.height / 2.0 - (v + 0.5)) / self.fy,
            ],
            axis=-1,
        )
        return d.reshape(-1, 3)

    def project(self, p_cam: np.ndarray) -> tuple[float, float] | None:
        """Pixel (u, v) of a camera-frame point, or None behind the camera."""
        if p_cam[0] <= 1e-3:
            return None
        return (
            self.width / 2.0 - self.fx * p_cam[1] / p_cam[0],
            self.height / 2.0 - self.fy * p_cam[2] / p_cam[0],
        )
