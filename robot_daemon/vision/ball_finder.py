"""The ball finder: HSV colour segmentation, morphology, blob choice, centroid → angular error.

The ROBOTIS framework's ColorFinder (hue 356 ± 15 of 0..360, saturation > 50 %, value > 10 %,
erode then dilate 3×3, 0.07 %..30 % of the image) takes the centroid of *every* matching pixel
and gives up when the total is out of bounds, so a red shirt in the background hides the ball.
Here each connected blob is judged on its own (area bounds, and a shape check a disc passes and a
shirt or a stripe does not) and the best one is the ball.

Angular errors follow the framework's BallTracker: (centre − pixel) × field of view / image size,
so a positive pan error is a ball to the robot's left and a positive tilt error a ball above the
image centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from config.loader import section_to
from robot_daemon.vision.opencv import opencv
from schemas.errors import ConfigError
from schemas.messages import BallDetection


@dataclass(frozen=True)
class ColorRange:
    """A colour in HSV: hue in degrees (0..360) ± tolerance, minimum saturation/value in %."""

    name: str
    hue: float
    hue_tolerance: float
    min_saturation: float
    min_value: float

    def mask(self, hsv: np.ndarray) -> np.ndarray:
        """uint8 mask (255 = this colour) of an OpenCV HSV image (H 0..180, S and V 0..255)."""
        h = hsv[..., 0].astype(np.int16) * 2  # OpenCV stores hue/2
        dh = np.abs((h - int(round(self.hue)) + 180) % 360 - 180)
        ok = dh <= self.hue_tolerance
        ok &= hsv[..., 1] > self.min_saturation * 255.0 / 100.0
        ok &= hsv[..., 2] > self.min_value * 255.0 / 100.0
        return ok.astype(np.uint8) * 255


@dataclass(frozen=True)
class CameraView:
    """``[ballplay.camera]``: the image the finder expects and the lens's field of view."""

    width: int = 320
    height: int = 240
    fov_h_deg: float = 58.0
    fov_v_deg: float = 46.0


@dataclass(frozen=True)
class FinderSettings:
    color: ColorRange
    min_area_percent: float = 0.07
    max_area_percent: float = 30.0
    erode: int = 3
    dilate: int = 3
    min_fill: float = 0.45
    max_aspect: float = 2.2
    fov_h_deg: float = 58.0
    fov_v_deg: float = 46.0

    @classmethod
    def from_config(cls, ballplay: dict[str, Any], color: str | None = None) -> FinderSettings:
        """Settings from the ``[ballplay]`` section; ``color`` names one of its colours."""
        camera = section_to(CameraView, ballplay.get("camera", {}), "ballplay.camera")
        return section_to(
            cls,
            ballplay.get("finder", {}),
            "ballplay.finder",
            color=color_range(ballplay, color or str(ballplay.get("color", "red"))),
            fov_h_deg=camera.fov_h_deg,
            fov_v_deg=camera.fov_v_deg,
        )


def color_names(ballplay: dict[str, Any]) -> list[str]:
    return sorted(ballplay.get("colors", {}))


def color_range(ballplay: dict[str, Any], name: str) -> ColorRange:
    """The named colour of ``[ballplay.colors]``; ``ConfigError`` listing the known ones."""
    table = ballplay.get("colors", {}).get(name)
    if table is None:
        raise ConfigError(
            f"unknown ball colour {name!r}: known colours are {', '.join(color_names(ballplay))}"
            " (add one under [ballplay.colors.<name>])"
        )
    return section_to(ColorRange, table, f"ballplay.colors.{name}", name=name)


@dataclass
class Blob:
    x: float  # centroid, pixels
    y: float
    area: int  # pixels
    fill: float  # area / bounding-box area
    aspect: float  # longest / shortest side of the bounding box


class BallFinder:
    """Finds the ball in BGR images (320×240 or any size; angles scale with the size)."""

    def __init__(self, settings: FinderSettings) -> None:
        opencv("ball finding")  # MissingExtraError now, before ball play starts, not later
        self.settings = settings
        s = settings
        self._erode = np.ones((s.erode, s.erode), np.uint8) if s.erode > 1 else None
        self._dilate = np.ones((s.dilate, s.dilate), np.uint8) if s.dilate > 1 else None

    def mask(self, bgr: np.ndarray) -> np.ndarray:
        """The colour mask after morphology (what blobs are taken from)."""
        if bgr.ndim != 3 or bgr.shape[2] != 3:
            raise ValueError(f"expected a BGR image of shape (h, w, 3), got shape {bgr.shape}")
        cv2 = opencv()
        hsv = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)
        m = self.settings.color.mask(hsv)
        if self._erode is not None:
            m = cv2.erode(m, self._erode)
        if self._dilate is not None:
            m = cv2.dilate(m, self._dilate)
        return m

    def blobs(self, mask: np.ndarray) -> list[Blob]:
        n, _, stats, centroids = opencv().connectedComponentsWithStats(mask, connectivity=8)
        out = []
        for i in range(1, n):
            w, h, area = (int(v) for v in stats[i, 2:5])
            out.append(
                Blob(
                    x=float(centroids[i, 0]),
                    y=float(centroids[i, 1]),
                    area=area,
                    fill=area / float(w * h),
                    aspect=max(w, h) / float(max(1, min(w, h))),
                )
            )
        return out

    def is_ball(self, blob: Blob, image_area: int) -> bool:
        s = self.settings
        percent = 100.0 * blob.area / image_area
        return (
            s.min_area_percent <= percent <= s.max_area_percent
            and blob.fill >= s.min_fill
            and blob.aspect <= s.max_aspect
        )

    def find(self, bgr: np.ndarray, stamp: float = 0.0, phase: str = "") -> BallDetection:
        height, width = bgr.shape[:2]
        candidates = [b for b in self.blobs(self.mask(bgr)) if self.is_ball(b, width * height)]
        if not candidates:
            return BallDetection(found=False, width=width, height=height, phase=phase, stamp=stamp)
        # The biggest plausible disc: the ball is usually the nearest red thing that is round.
        best = max(candidates, key=lambda b: b.area * min(1.0, b.fill / 0.785))
        pan, tilt = self.angles(best.x, best.y, width, height)
        return BallDetection(
            found=True,
            x=best.x,
            y=best.y,
            pan_error=pan,
            tilt_error=tilt,
            size=best.area / float(width * height),
            width=width,
            height=height,
            phase=phase,
            stamp=stamp,
        )

    def angles(self, x: float, y: float, width: int, height: int) -> tuple[float, float]:
        """Pixel → (pan, tilt) error in rad, the framework's linear pixel-per-angle law."""
        s = self.settings
        pan = (width / 2.0 - x) * math.radians(s.fov_h_deg) / width
        tilt = (height / 2.0 - y) * math.radians(s.fov_v_deg) / height
        return pan, tilt
