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
from functools import cached_property
from typing import Any

import numpy as np

from config.loader import section_to
from robot_daemon.vision.camera_view import CameraView
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
        if hsv.dtype != np.uint8 or hsv.ndim != 3 or hsv.shape[2] != 3:
            h, s, v = hsv[..., 0], hsv[..., 1], hsv[..., 2]
            return (self._hue_ok(h) & self._saturated(s) & self._bright(v)).astype(np.uint8) * 255
        # An 8-bit image through OpenCV's range test: a frame's numpy arithmetic cost 0.8 ms of
        # the finder's 2.2.
        cv2 = opencv()
        out: np.ndarray | None = None
        for low, high in self._boxes:
            inside = cv2.inRange(hsv, low, high)
            out = inside if out is None else cv2.bitwise_or(out, inside)
        return out if out is not None else np.zeros(hsv.shape[:2], np.uint8)

    def _hue_ok(self, h: np.ndarray) -> np.ndarray:
        h = h.astype(np.int16) * 2  # OpenCV stores hue/2
        return np.abs((h - int(round(self.hue)) + 180) % 360 - 180) <= self.hue_tolerance

    def _saturated(self, s: np.ndarray) -> np.ndarray:
        return s > self.min_saturation * 255.0 / 100.0

    def _bright(self, v: np.ndarray) -> np.ndarray:
        return v > self.min_value * 255.0 / 100.0

    @cached_property
    def _boxes(self) -> list[tuple[tuple[int, int, int], tuple[int, int, int]]]:
        """The colour as inclusive (low, high) HSV boxes over 8-bit values, for ``cv2.inRange``:
        the channel tests above, each taken at every level (the hue's wrap makes two boxes)."""
        levels = np.arange(256)
        runs = [_runs(test(levels)) for test in (self._hue_ok, self._saturated, self._bright)]
        if not runs[1] or not runs[2]:
            return []
        (s0, s1), (v0, v1) = runs[1][0], runs[2][0]  # a threshold passes one run of levels
        return [((h0, s0, v0), (h1, s1, v1)) for h0, h1 in runs[0]]


def _runs(ok: np.ndarray) -> list[tuple[int, int]]:
    """The (first, last) indices of each run of True in ``ok``."""
    edges = np.flatnonzero(np.diff(np.concatenate(([False], ok, [False])).astype(np.int8)))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


@dataclass(frozen=True)
class FinderSettings:
    """What the ball finder looks for: a colour, a blob's size and shape, and the lens's field of
    view."""

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
    """One blob of the ball's colour: its centroid, area and shape."""

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
        cv2 = opencv()
        # Labelled inside the box around the mask's pixels, not the whole frame (0.7 ms of the
        # finder's 2.2 for a blob or two). OpenCV labels 2×2 blocks of pixels in raster order:
        # the box starts on the frame's blocks, so the blobs come in the same order.
        left, top, width, height = cv2.boundingRect(mask)
        if width == 0:
            return []
        left, top = left & ~1, top & ~1
        box = mask[top:, left:][: height + 1, : width + 1]
        n, _, stats, centroids = cv2.connectedComponentsWithStats(box, connectivity=8)
        out = []
        for i in range(1, n):
            w, h, area = (int(v) for v in stats[i, 2:5])
            out.append(
                Blob(
                    # OpenCV's centroid is the pixels' integer coordinate sum / area: that sum
                    # back, shifted to the frame, gives the whole frame's centroid to the bit.
                    x=(round(centroids[i, 0] * area) + area * left) / area,
                    y=(round(centroids[i, 1] * area) + area * top) / area,
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
