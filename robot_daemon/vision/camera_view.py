"""The camera as the ball finder sees it. Apart from the finder so that the simulated world's
settings, which name the same lens, load without the finder (OpenCV's wrapper, the detection
message) when nobody watches its camera (``darwin up --camera none``)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class CameraView:
    """``[ballplay.camera]``: the image the finder expects and the lens's field of view."""

    width: int = 320
    height: int = 240
    fov_h_deg: float = 58.0
    fov_v_deg: float = 46.0
