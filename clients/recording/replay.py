"""``Replayer``: republish a recording's original msgpack payloads on ``darwin/<robot>/…`` with
the recorded timing (scaled by ``rate``), so the TUI, the notebook client and the gateway show
a recorded session as if it were live.

A queryable on ``Keys(robot).replay_control`` takes ``{"v", "op": "pause" | "resume" | "seek" |
"rate" | "status", "t": seconds, "rate": factor}`` (msgpack, through :mod:`schemas.query`) and
answers with the replay's status (``ok_reply("replay", status)``);
:class:`clients.recording.control.ReplayControl` is its client.
"""

from __future__ import annotations

import bisect
import logging
import math
import os
import threading
import time
from collections.abc import Iterable
from typing import Any, Self

import zenoh

from clients.recording.reader import Recording, read_recording
from schemas import qos
from schemas.errors import ErrorCode, InvalidCommandError, StateError, brief
from schemas.keys import Keys
from schemas.query import serve

log = logging.getLogger(__name__)

MAX_RATE = 100.0
# How long (µs) a replayed sample waits for room in a slow subscriber's link queue before Zenoh
# closes that link (``server_config(block_wait_us=…)`` of a listening replay). The daemon's
# 0.5 s closed the link of a test's subscriber that a loaded host had not run for half a second,
# and it lost every sample queued for it. Longer than the link lease (3 s): a subscriber whose
# link is cut is closed by its lease, one whose link lives is waited for (the replay slows
# down) until it has taken nothing for this long (hung), so the others go on.
BLOCK_WAIT_US = 5_000_000
# At its end a replay that exits keeps its session open while anyone still subscribes, up to
# this long (s): Zenoh takes a link down as soon as its session closes, and a subscriber still
# behind (a loaded host) lost the samples it had received but not yet read.
END_LINGER_S = 5.0


def default_robot_name(rec: Recording) -> str:
    return f"{rec.robot}-replay" if rec.robot else "replay"


def check_rate(rate: Any) -> float:
    if isinstance(rate, bool) or not isinstance(rate, int | float) or not math.isfinite(rate):
        raise InvalidCommandError(ErrorCode.INVALID, f"rate {rate!r} is not a number", "rate")
    if not 0 < rate <= MAX_RATE:
        raise InvalidCommandError(
            ErrorCode.OUT_OF_RANGE, f"rate {rate} is outside (0, {MAX_RATE:g}]", "rate"
        )
    return float(rate)


class Replayer:
    """Play ``recording`` (a :class:`Recording` or a path) on ``session`` as robot ``robot``."""

    def __init__(
        self,
        recording: Recording | str | os.PathLike[str],
        session: zenoh.Session,
        robot: str | None = None,
        *,
        rate: float = 1.0,
        loop: bool = False,
        topics: Iterable[str] | None = None,
    ) -> None:
        self.recording = (
            recording if isinstance(recording, Recording) else read_recording(recording)
        )
        wanted = set(topics) if topics is not None else None
        self._msgs = [m for m in self.recording.messages if wanted is None or m.topic in wanted]
        start = self._msgs[0].log_ns if self._msgs else 0
        self._rel = [(m.log_ns - start) / 1e9 for m in self._msgs]
        self.duration = self._rel[-1] if self._rel else 0.0
        self.keys = Keys(robot or default_robot_name(self.recording))
        self._session = session
        self._rate = check_rate(rate)
        self.loop = loop
        self._cond = threading.Condition()
        self._index = 0
        self._anchor_pos = 0.0  # recording time (s) at _anchor_mono
        self._anchor_mono = 0.0
        self._paused = False
        self._state = "new"  # new | playing | paused | finished | stopped
        self._loops = 0
        self.published = 0
        self._finished = threading.Event()
        self._pubs: dict[str, Any] = {}
        self._queryable: Any = None
        self._token: Any = None
        self._thread: threading.Thread | None = None

    def __repr__(self) -> str:
        st = self.status()
        return (
            f"<Replayer {self.recording.path} as {self.keys.robot}: {st['state']} "
            f"{st['position']:.1f}/{st['duration']:.1f} s at {st['rate']:g}x>"
        )

    # -- lifecycle ------------------------------------------------------------------------------
    def start(self, paused: bool = False) -> Self:
        if self._state != "new":
            raise StateError(f"this Replayer is {self._state}; create a new one")
        topics = self.keys.topics()
        for t in {m.topic for m in self._msgs}:
            # BLOCK: a replay is not a control loop, and dropping recorded samples would make
            # the replay differ from the recording.
            self._pubs[t] = self._session.declare_publisher(
                topics[t], **qos.for_key(topics[t]).lossless().kwargs()
            )
        self._queryable = serve(
            self._session,
            self.keys.replay_control,
            self._control,
            what="replay",
            empty={"op": "status"},
        )
        # Viewers (the TUI) show a robot as connected while its `alive` token exists: the
        # replayed robot is "up" for as long as the replay runs.
        self._token = self._session.liveliness().declare_token(self.keys.alive)
        with self._cond:
            self._anchor_mono = time.monotonic()
            self._paused = paused
            self._state = "paused" if paused else "playing"
        self._thread = threading.Thread(target=self._run, name="darwin-replay", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        with self._cond:
            if self._state == "stopped":
                return
            self._state = "stopped"
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join()
        for obj in (self._token, self._queryable, *self._pubs.values()):
            if obj is not None:
                try:
                    obj.undeclare()
                except zenoh.ZError as exc:
                    log.debug("undeclaring a replay entity: %s", exc)
        self._pubs.clear()
        self._finished.set()

    def __enter__(self) -> Self:
        return self if self._state != "new" else self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the recording has played to its end (never, with ``loop``)."""
        return self._finished.wait(timeout)

    def watched(self, topic: str) -> bool:
        """True when some subscriber matches the replay's publisher of ``topic``."""
        pub = self._pubs.get(topic)
        return pub is not None and pub.matching_status.matching

    def linger(self, stop: threading.Event, timeout: float = END_LINGER_S) -> None:
        """Return once no subscriber matches any of the replay's topics, ``stop`` is set or
        ``timeout`` passed: what a subscriber still behind takes before the session closes."""
        deadline = time.monotonic() + timeout
        while any(map(self.watched, list(self._pubs))) and time.monotonic() < deadline:
            if stop.wait(0.05):  # a check of Zenoh's matching state, and a signal ends it
                return

    # -- control (thread-safe) ------------------------------------------------------------------
    def _position(self) -> float:
        if self._paused or self._state != "playing":
            return self._anchor_pos
        pos = self._anchor_pos + (time.monotonic() - self._anchor_mono) * self._rate
        return min(pos, self.duration)

    def _reanchor(self, pos: float) -> None:
        self._anchor_pos = pos
        self._anchor_mono = time.monotonic()

    def pause(self) -> dict[str, Any]:
        with self._cond:
            if self._state == "playing":
                self._reanchor(self._position())
                self._paused = True
                self._state = "paused"
            self._cond.notify_all()
        return self.status()

    def resume(self) -> dict[str, Any]:
        with self._cond:
            if self._state == "paused":
                self._reanchor(self._anchor_pos)
                self._paused = False
                self._state = "playing"
            self._cond.notify_all()
        return self.status()

    def seek(self, t: float) -> dict[str, Any]:
        """Go to ``t`` seconds from the start of the recording (keeps paused/playing)."""
        if isinstance(t, bool) or not isinstance(t, int | float) or not math.isfinite(t):
            raise InvalidCommandError(ErrorCode.INVALID, f"seek time {t!r} is not a number", "t")
        if not 0 <= t <= self.duration:
            raise InvalidCommandError(
                ErrorCode.OUT_OF_RANGE,
                f"seek time {t} s is outside the recording (0 to {self.duration:.3f} s)",
                "t",
            )
        with self._cond:
            self._index = bisect.bisect_left(self._rel, t)
            self._reanchor(float(t))
            if self._state == "finished":
                self._state = "playing"
                self._paused = False
                self._finished.clear()
            self._cond.notify_all()
        return self.status()

    def set_rate(self, rate: float) -> dict[str, Any]:
        rate = check_rate(rate)
        with self._cond:
            self._reanchor(self._position())
            self._rate = rate
            self._cond.notify_all()
        return self.status()

    def status(self) -> dict[str, Any]:
        with self._cond:
            return {
                "state": self._state,
                "position": round(self._position(), 6),
                "duration": round(self.duration, 6),
                "rate": self._rate,
                "loop": self.loop,
                "loops": self._loops,
                "index": self._index,
                "count": len(self._msgs),
                "published": self.published,
                "robot": self.keys.robot,
                "source_robot": self.recording.robot,
                "path": self.recording.path,
            }

    # -- the playback thread --------------------------------------------------------------------
    def _run(self) -> None:
        with self._cond:
            while self._state != "stopped":
                if self._state in {"paused", "finished"}:
                    self._cond.wait()
                    continue
                if self._index >= len(self._msgs):
                    if self.loop and self._msgs:
                        self._loops += 1
                        self._index = 0
                        self._reanchor(0.0)
                        continue
                    self._reanchor(self.duration)
                    self._state = "finished"
                    self._finished.set()
                    continue
                due = self._anchor_mono + (self._rel[self._index] - self._anchor_pos) / self._rate
                delay = due - time.monotonic()
                if delay > 0:
                    # Woken early by a control change: recompute against the new anchor.
                    self._cond.wait(delay)
                    continue
                msg = self._msgs[self._index]
                self._index += 1
                self._pubs[msg.topic].put(msg.payload)
                self.published += 1

    # -- the control queryable ------------------------------------------------------------------
    def _control(self, req: dict[str, Any]) -> dict[str, Any]:
        op = req.get("op", "status")
        if op == "pause":
            return self.pause()
        if op == "resume":
            return self.resume()
        if op == "seek":
            return self.seek(req.get("t"))  # type: ignore[arg-type]  # seek() checks it
        if op == "rate":
            return self.set_rate(req.get("rate"))  # type: ignore[arg-type]  # checked there
        if op == "status":
            return self.status()
        raise InvalidCommandError(
            ErrorCode.INVALID,
            f"unknown op {brief(op)}; use pause, resume, seek (t), rate (rate) or status",
            "op",
        )
