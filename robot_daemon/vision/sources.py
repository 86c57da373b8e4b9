"""Camera sources: where frames come from. A source is anything with ``read()`` (a BGR
``np.ndarray``, the camera's own JPEG as a :class:`JpegFrame`, or None when no frame is ready)
and ``close()``.

``open_source(spec, ctx)`` picks one: ``"none"``, a device index (``"0"``) or path
(``"/dev/video0"``) for a V4L2 camera asked for MJPEG (:mod:`robot_daemon.vision.v4l2`, no
OpenCV; a camera without MJPEG falls back to OpenCV's capture when OpenCV is installed),
``"pattern"`` for a synthetic test pattern (needs OpenCV), or any name
registered with :func:`register_source` — e.g. the simulated world registers ``"sim"`` (from the
module :data:`PLUGIN_MODULES` names). Until a plugin registers ``"sim"``, it is the test pattern.
"""

from __future__ import annotations

import importlib
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from robot_daemon.vision.frames import Frame
from robot_daemon.vision.opencv import opencv
from schemas.errors import DarwinError

log = logging.getLogger(__name__)

# Modules imported on first use so they can register their sources (missing ones are skipped).
PLUGIN_MODULES = ("robot_daemon.plant.camera_source",)


class CameraSource(Protocol):
    def read(self) -> Frame | None: ...
    def close(self) -> None: ...


@dataclass
class SourceContext:
    """What a camera source is made with: the frame size and rate, and the daemon's session and
    config."""

    width: int = 320
    height: int = 240
    fps: float = 30.0
    session: Any = None  # the daemon's Zenoh session (a sim source may subscribe to the world)
    robot: str = "op1"
    settings: dict[str, Any] = field(default_factory=dict)


SourceFactory = Callable[[SourceContext], CameraSource]

_SOURCES: dict[str, SourceFactory] = {}
_plugins_loaded = False


class CameraError(DarwinError):
    pass


def register_source(name: str, factory: SourceFactory) -> None:
    """Make ``--camera NAME`` open ``factory(ctx)``; a later registration replaces it."""
    _SOURCES[name] = factory


def _load_plugins() -> None:
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    for mod in PLUGIN_MODULES:
        try:
            importlib.import_module(mod)
        except ModuleNotFoundError as exc:
            if exc.name and mod.startswith(exc.name):
                continue
            raise


def source_names() -> list[str]:
    _load_plugins()
    return sorted({"none", "pattern", "sim", *_SOURCES})


def check_spec(spec: str) -> str:
    """``spec`` if some source can open it, else ``CameraError`` listing the choices."""
    if spec in source_names() or spec.isdigit() or spec.startswith("/dev/"):
        return spec
    raise CameraError(
        f"unknown camera {spec!r}: use none, sim, pattern, a device index (0) or a path "
        f"(/dev/video0); registered: {', '.join(source_names())}"
    )


def open_source(spec: str, ctx: SourceContext) -> CameraSource | None:
    """The source for ``spec``, or None for ``"none"``."""
    _load_plugins()
    if spec == "none":
        return None
    if spec in _SOURCES:
        return _SOURCES[spec](ctx)
    if spec in ("pattern", "sim"):
        return TestPatternSource(ctx.width, ctx.height)
    check_spec(spec)
    # Here, not at the top: its ctypes structures cost a daemon ~7 ms of CPU at start, and only a
    # device camera needs them (a daemon on the emulator, or with no camera, never does).
    from robot_daemon.vision.v4l2 import V4L2Error, V4L2Source

    path = f"/dev/video{spec}" if spec.isdigit() else spec
    try:
        return V4L2Source(path, ctx.width, ctx.height, ctx.fps)
    except V4L2Error as exc:
        if "MJPEG" not in str(exc):
            raise
        try:
            opencv()
        except DarwinError:
            raise exc from None
        log.info("%s; using OpenCV's capture (decoded, then re-encoded for viewers)", exc)
    return OpenCVSource(int(spec) if spec.isdigit() else spec, ctx.width, ctx.height, ctx.fps)


class OpenCVSource:
    """A V4L2 camera through OpenCV (a camera without MJPEG: raw frames, encoded for viewers)."""

    def __init__(self, device: int | str, width: int, height: int, fps: float) -> None:
        cv2 = opencv("a camera without MJPEG")
        self.device = device
        self.cap = cv2.VideoCapture(device, cv2.CAP_V4L2)
        if not self.cap.isOpened():
            raise CameraError(
                f"cannot open camera {device!r}: is it plugged in (`ls /dev/video*`) and are "
                "you in the 'video' group? Use --camera none to run without it"
            )
        self.cap.set(cv2.CAP_PROP_FRAME_WIDTH, width)
        self.cap.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
        self.cap.set(cv2.CAP_PROP_FPS, fps)

    def read(self) -> np.ndarray | None:
        ok, frame = self.cap.read()
        return frame if ok else None

    def close(self) -> None:
        self.cap.release()


class TestPatternSource:
    """Colour bars with a red ball circling over them: a frame that shows motion and colour."""

    __test__ = False  # not a pytest class

    def __init__(self, width: int = 320, height: int = 240) -> None:
        self._cv2 = opencv("the test pattern camera")
        self.width, self.height = width, height
        bars = np.zeros((height, width, 3), dtype=np.uint8)
        colours = [(255, 255, 255), (0, 255, 255), (255, 255, 0), (0, 255, 0), (255, 0, 255)]
        for i, c in enumerate(colours):
            bars[:, i * width // len(colours) : (i + 1) * width // len(colours)] = c
        bars[height * 3 // 4 :] = (64, 64, 64)
        self._bars = bars
        self._t0 = time.monotonic()
        self.frames = 0

    def read(self) -> np.ndarray:
        t = time.monotonic() - self._t0
        img = self._bars.copy()
        cx = int(self.width / 2 + self.width / 4 * math.cos(t))
        cy = int(self.height / 2 + self.height / 4 * math.sin(t))
        cv2 = self._cv2
        cv2.circle(img, (cx, cy), max(4, self.height // 12), (0, 0, 230), -1)
        self.frames += 1
        cv2.putText(
            img, f"{self.frames}", (4, self.height - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255,) * 3
        )
        return img

    def close(self) -> None:
        pass
