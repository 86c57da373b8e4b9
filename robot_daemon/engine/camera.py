"""The camera thread: the one owner of the camera source, capturing only while someone needs it.

Two kinds of consumer need frames: Zenoh subscribers of the camera key (a matching listener on
the publisher says when the first arrives and the last leaves) and in-daemon readers such as
ball vision (:meth:`CameraThread.consumer`). While either is there, the thread reads the source
at its frame rate (absolute deadlines), publishes when someone subscribes, and hands the frame to
every reader. A source that gives JPEG (a V4L2 camera in MJPEG, the simulated world) is passed
through byte for byte: no decoding, no re-encoding, no OpenCV. Only a reader decodes, when it
reads (ball vision, at the vision rate: a frame it skips is never decoded); only a source of raw
frames (the test pattern, OpenCV's capture) is JPEG-encoded, and only when someone subscribes.
The source is opened once for all of them, and closed when nobody needs frames. Never in the
motion loop.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from typing import Any

import numpy as np
import zenoh

from robot_daemon.vision.frames import Frame, JpegFrame, pixels
from robot_daemon.vision.opencv import encode_jpeg
from robot_daemon.vision.sources import CameraSource, SourceContext, open_source
from schemas import qos
from schemas.keys import Keys
from schemas.messages import CameraFrame, encode

log = logging.getLogger(__name__)

# How long a reader waits for the next frame before it gets None (a stalled source).
READ_TIMEOUT = 2.0


class FrameConsumer:
    """A reader of the camera owner's frames (newest only); capture runs while it is open."""

    def __init__(self, owner: CameraThread) -> None:
        self._owner = owner
        self._cond = threading.Condition()
        self._frame: Frame | None = None
        self._closed = False
        self.decoded = 0  # JPEG frames decoded for this reader (only those it read)

    def offer(self, frame: Frame) -> None:
        with self._cond:
            self._frame = frame
            self._cond.notify_all()

    def read(self, timeout: float = READ_TIMEOUT) -> np.ndarray | None:
        """The next frame captured since the last read as a BGR image (decoded here, in the
        reader's thread), or None after ``timeout``."""
        with self._cond:
            self._cond.wait_for(lambda: self._frame is not None or self._closed, timeout)
            frame, self._frame = self._frame, None
        if frame is None:
            return None
        self.decoded += isinstance(frame, JpegFrame)
        return pixels(frame)

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        self._owner._remove(self)


class CameraThread:
    def __init__(
        self,
        session: zenoh.Session,
        keys: Keys,
        spec: str,
        ctx: SourceContext,
        quality: int = 80,
    ) -> None:
        self.spec = spec
        self.ctx = ctx
        self.quality = quality
        self.period = 1.0 / max(ctx.fps, 1.0)
        self.opened = 0  # times the source was opened (once per stretch of being needed)
        self.captured = 0
        self.published = 0
        self.passed_through = 0  # published as the source's own JPEG bytes
        # Between a need and the source closed again: a capture may still complete (a render
        # under way when the last viewer left), so counts settle once this is False.
        self.capturing = False
        self.errors = 0
        self.last_error = ""
        self._source: CameraSource | None = None
        self._cond = threading.Condition()
        self._subscribed = False
        self._consumers: list[FrameConsumer] = []
        self._stop = False
        self._pub = session.declare_publisher(
            keys.camera_jpeg, **qos.for_key(keys.camera_jpeg).kwargs()
        )
        self._listener = self._pub.declare_matching_listener(self._on_matching)
        # zenoh's stubs type matching_status as a bool; it is a MatchingStatus.
        self._subscribed = bool(self._pub.matching_status.matching)  # type: ignore[attr-defined]
        self._thread = threading.Thread(target=self._run, name="camera", daemon=True)
        self._thread.start()

    @classmethod
    def from_settings(
        cls, session: zenoh.Session, keys: Keys, spec: str, settings: dict[str, Any]
    ) -> CameraThread:
        cam = settings.get("daemon", {}).get("camera", {})
        ctx = SourceContext(
            width=int(cam.get("width", 320)),
            height=int(cam.get("height", 240)),
            fps=float(cam.get("fps", 30)),
            session=session,
            robot=keys.robot,
            settings=settings,
        )
        return cls(session, keys, spec, ctx, int(cam.get("jpeg_quality", 80)))

    def _on_matching(self, status: zenoh.MatchingStatus) -> None:
        with self._cond:
            self._subscribed = status.matching
            self._cond.notify_all()

    def consumer(self) -> FrameConsumer:
        """A reader of this camera's frames; capture runs until it is closed."""
        reader = FrameConsumer(self)
        with self._cond:
            self._consumers.append(reader)
            self._cond.notify_all()
        return reader

    def _remove(self, reader: FrameConsumer) -> None:
        with self._cond:
            if reader in self._consumers:
                self._consumers.remove(reader)
            self._cond.notify_all()

    def _needed(self) -> bool:
        return self._subscribed or bool(self._consumers)

    def _run(self) -> None:
        next_t = time.monotonic()
        while True:
            with self._cond:
                while not self._needed() and not self._stop:
                    self._close_source()
                    self.capturing = False
                    self._cond.wait()
                if self._stop:
                    self._close_source()
                    self.capturing = False
                    return
                self.capturing = True
            next_t = max(next_t + self.period, time.monotonic())
            self._capture_one()
            with self._cond:
                if not self._stop:
                    self._cond.wait(max(0.0, next_t - time.monotonic()))

    def _capture_one(self) -> None:
        try:
            if self._source is None:
                self._source = open_source(self.spec, self.ctx)
                if self._source is None:
                    self._stop = True
                    return
                self.opened += 1
            frame = self._source.read()
            if frame is None:
                return
            self.captured += 1
            with self._cond:
                readers, subscribed = list(self._consumers), self._subscribed
            for reader in readers:
                reader.offer(frame)
            if not subscribed:
                return  # only in-daemon readers: no JPEG nobody receives
            if passed := isinstance(frame, JpegFrame):
                jpeg, w, h = frame.jpeg, frame.width, frame.height
            else:
                jpeg, (h, w) = encode_jpeg(frame, self.quality), frame.shape[:2]
            msg = CameraFrame(jpeg=jpeg, width=w, height=h, seq=self.captured)
            self._pub.put(encode(msg))
            self.published += 1
            self.passed_through += passed  # of those published: never ahead of the count
        except Exception as exc:  # a camera unplugged mid-run: report, retry after a pause
            self.errors += 1
            self.last_error = str(exc)
            log.warning("camera %s: %s", self.spec, exc)
            self._close_source()
            with self._cond:
                self._cond.wait(1.0)

    def _close_source(self) -> None:
        if self._source is not None:
            with contextlib.suppress(Exception):
                self._source.close()
            self._source = None

    def status(self) -> dict[str, Any]:
        return {
            "source": self.spec,
            "subscribed": self._subscribed,
            "capturing": self.capturing,
            "readers": len(self._consumers),
            "opened": self.opened,
            "captured": self.captured,
            "published": self.published,
            "passed_through": self.passed_through,
            "errors": self.errors,
            "last_error": self.last_error,
            "fps": self.ctx.fps,
            "width": self.ctx.width,
            "height": self.ctx.height,
        }

    def close(self) -> None:
        with self._cond:
            self._stop = True
            readers = list(self._consumers)
            self._cond.notify_all()
        for reader in readers:
            reader.close()
        self._thread.join(timeout=2.0)
        with contextlib.suppress(Exception):
            self._listener.undeclare()
        with contextlib.suppress(Exception):
            self._pub.undeclare()
