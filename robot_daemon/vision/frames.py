"""What a camera source gives: a BGR image (``np.ndarray``) or the camera's own JPEG bytes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_daemon.vision.opencv import decode_jpeg


@dataclass(frozen=True)
class JpegFrame:
    """One compressed frame as the camera (or the simulated world) made it: forwarded to viewers
    untouched, decoded only by a reader that needs pixels (ball vision)."""

    jpeg: bytes
    width: int
    height: int


Frame = np.ndarray | JpegFrame


def pixels(frame: Frame) -> np.ndarray:
    """The frame as a BGR image (decoding a JPEG: OpenCV, the vision extra)."""
    return decode_jpeg(frame.jpeg) if isinstance(frame, JpegFrame) else frame
