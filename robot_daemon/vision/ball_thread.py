"""The ball finder's thread in the daemon: vision never runs in the 8 ms motion loop.

While ball play runs, this thread reads the frames of the daemon's one camera owner (a reader
from ``CameraThread.consumer``; it never opens a source of its own) at the vision rate
(absolute deadlines, waiting on an Event between frames), finds the ball, hands each detection
to the ball play module (its newest-only slot) and publishes it on ``Keys.vision_ball``. It ends
by itself when ball play ends (done, lost, stopped), after publishing a last detection that
carries the final phase.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from robot_daemon.services import FrameReader
from robot_daemon.vision.ball_finder import BallFinder
from schemas.messages import BallDetection

log = logging.getLogger(__name__)


class BallPlayer(Protocol):
    phase: str

    @property
    def playing(self) -> bool: ...
    def offer(self, detection: BallDetection) -> None: ...


class BallVision:
    def __init__(
        self,
        open_reader: Callable[[], FrameReader],
        finder: BallFinder,
        player: BallPlayer,
        publish: Callable[[BallDetection], None] | None = None,
        hz: float = 30.0,
    ) -> None:
        self._open = open_reader
        self.finder = finder
        self.player = player
        self.publish = publish
        self.period = 1.0 / max(1.0, hz)
        self.frames = 0
        self.found = 0
        self.errors = 0
        self.last_error = ""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="ball-vision", daemon=True)

    def start(self) -> BallVision:
        self._thread.start()
        return self

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout)

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def _run(self) -> None:
        source: FrameReader | None = None
        next_t = time.monotonic()
        try:
            while not self._stop.is_set():
                # The module is started by the same command that starts this thread, so a
                # phase that is no longer active means ball play ended.
                if not self.player.playing:
                    self._publish(BallDetection(found=False, phase=self.player.phase))
                    return
                if source is None:
                    source = self._open()
                self._one(source)
                next_t = max(next_t + self.period, time.monotonic())
                self._stop.wait(max(0.0, next_t - time.monotonic()))
        except Exception as exc:  # a vanished camera: report it, ball play sees no ball
            self.errors += 1
            self.last_error = str(exc)
            log.warning("ball vision stopped: %s", exc)
        finally:
            if source is not None:
                with contextlib.suppress(Exception):
                    source.close()

    def _one(self, source: FrameReader) -> None:
        img = source.read()
        if img is None:
            return
        det = self.finder.find(img, stamp=time.time(), phase=self.player.phase)
        self.frames += 1
        self.found += int(det.found)
        self.player.offer(det)
        self._publish(det)

    def _publish(self, det: BallDetection) -> None:
        if self.publish is not None:
            try:
                self.publish(det)
            except Exception as exc:  # a closed session at shutdown must not kill the thread
                log.debug("ball detection not published: %s", exc)

    def status(self) -> dict[str, Any]:
        return {
            "running": self.running,
            "frames": self.frames,
            "found": self.found,
            "errors": self.errors,
            "last_error": self.last_error,
        }
