"""OpenCV, imported only where vision runs: the daemon itself runs without it.

The robot's lean install has no OpenCV (it is the ``vision`` extra, or Debian's
``python3-opencv``): the camera forwards the camera's own JPEG bytes, and only ball vision (and
sources that make raw frames: the test pattern, an OpenCV capture) decode or encode, at their
own rate, through the functions here.
"""

from __future__ import annotations

from types import ModuleType

import numpy as np

from schemas.extras import require


def opencv(needed_for: str = "ball vision") -> ModuleType:
    """The ``cv2`` module, or :class:`~schemas.extras.MissingExtraError` in one line naming the
    extra (and, on the robot, Debian's package)."""
    return require("cv2", needed_for)


def decode_jpeg(data: bytes) -> np.ndarray:
    """A BGR image from JPEG bytes; ``ValueError`` when they are not a JPEG image."""
    cv2 = opencv()
    img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if img is None:
        raise ValueError(f"the camera sent {len(data)} bytes that are not a JPEG image")
    return img


def encode_jpeg(img: np.ndarray, quality: int) -> bytes:
    cv2 = opencv("a camera that gives raw frames (pattern, an OpenCV capture)")
    ok, jpeg = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return jpeg.tobytes()
