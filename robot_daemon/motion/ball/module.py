"""Ball play as a motion module: find the ball, follow it, kick it.

The module owns the head (pan/tilt) while it plays and drives it itself (tracking and search);
it commands the walking module (start, step and turn amplitudes, stop) and the action module
(the kick pages). It never runs vision: a finder thread (or the simulated clock) hands it
detections through :meth:`offer`, and :meth:`step` uses the newest one at most once, so the 8 ms
tick only does arithmetic.

Phases, reported in ``status()["phase"]`` and as ``ballplay`` events when they change:
``searching`` → ``tracking`` (ball seen, turning to it) → ``approaching`` (walking to it) →
``kicking`` → ``done`` after ``kicks`` kicks; ``lost`` when the search times out; ``stopped``
when told to stop; ``idle`` before the first start.
"""

from __future__ import annotations

import math
import threading
from typing import Any

from robot_daemon.frames import JointFrame
from robot_daemon.motion.ball.follower import Follower
from robot_daemon.motion.ball.settings import BallPlaySettings
from robot_daemon.motion.ball.tracker import HeadTracker
from robot_daemon.motion.ball.walk_port import WalkPort
from robot_daemon.motion.interface import MotionModule
from schemas.kinematics import HEAD_PAN_ID, HEAD_TILT_ID
from schemas.messages import BallDetection

HEAD = (HEAD_PAN_ID, HEAD_TILT_ID)
ACTIVE_PHASES = frozenset({"searching", "tracking", "approaching", "kicking"})
# Frames of a fresh start during which a kick is not considered (the head is still settling).
_SETTLE_FRAMES = 3


class BallPlayModule(MotionModule):
    name = "ball"

    def __init__(self, settings: BallPlaySettings | None = None) -> None:
        super().__init__()
        self.settings = s = settings or BallPlaySettings()
        self.tracker = HeadTracker(s.head, s.tracker)
        self.follower = Follower(s.follower, s.head)
        self.phase = "idle"
        self.color = s.color
        self.kicks = 0
        self.frames = 0
        self.last: BallDetection | None = None
        self._slot: BallDetection | None = None
        self._slot_lock = threading.Lock()
        self._head_goal: tuple[float, float] | None = None  # rad, the tracker's
        self._head_cmd: list[float] | None = None  # rad, written this tick
        self._last_frame_time: float | None = None
        self._kick_side = 0
        self._kick_started: float | None = None
        self._walk_stopped: float | None = None  # when the walk was seen stopped for the kick
        self._kick_playing = False
        self._pending_start = False

    # -- commands (motion thread, between ticks) ------------------------------------------------
    def start(self, color: str | None = None) -> None:
        """Begin (or restart) ball play: search, follow, kick."""
        self.color = color or self.settings.color
        self.kicks = 0
        self.frames = 0
        self._pending_start = True
        self._kick_side = 0
        self._kick_started = self._walk_stopped = None
        self._kick_playing = False
        with self._slot_lock:
            self._slot = None
        self.claim(HEAD)
        self._set_phase("searching", "ball play started: looking for the ball")

    def stop(self) -> None:
        """Stop playing: the walk finishes its step, the head stays where it is."""
        if self.phase in ACTIVE_PHASES:
            self._finish("stopped", "ball play stopped")

    def halt(self) -> None:
        if self.phase in ACTIVE_PHASES:
            self.phase = "stopped"
            self.emit("ballplay", "ball play halted", phase="stopped")
        self._head_goal = None

    def on_released(self, ids: set[int]) -> None:
        if self.phase == "kicking" and self._kick_playing:
            # The kick page drives the head too; take it back (the page plays on with the
            # legs) so the module keeps ticking and the eyes stay on the ball.
            self.claim(HEAD)
        elif self.phase in ACTIVE_PHASES:
            # Someone else took the head (a `head` command, a behaviour): give up cleanly.
            self._finish("stopped", "ball play stopped: another command took the head")

    @property
    def playing(self) -> bool:
        return self.phase in ACTIVE_PHASES

    @property
    def sequencing(self) -> bool:
        return self.playing

    def offer(self, detection: BallDetection) -> None:
        """Hand over a detection (any thread). Only the newest is kept."""
        with self._slot_lock:
            self._slot = detection

    # -- the tick ----------------------------------------------------------------------------------
    def step(self, frame: JointFrame) -> dict[int, float]:
        if self.phase not in ACTIVE_PHASES:
            return {}
        walk = WalkPort.of(self.manager)
        if self._pending_start:
            self._pending_start = False
            pan, tilt = (math.degrees(float(frame.position[j])) for j in HEAD)
            self.tracker.reset(pan, tilt, frame.time)
            self.follower.reset()
            self._last_frame_time = None
        with self._slot_lock:
            det, self._slot = self._slot, None
        if self.phase == "kicking":
            self._kick_tick(frame, walk)
        elif det is not None:
            self._vision_frame(det, frame, walk)
        return self._head_goals(frame)

    def _vision_frame(self, det: BallDetection, frame: JointFrame, walk: WalkPort) -> None:
        self.last = det
        self.frames += 1
        now = frame.time
        dt = 1.0 / self.settings.vision_hz
        if self._last_frame_time is not None:
            dt = max(1e-3, now - self._last_frame_time)
        self._last_frame_time = now
        pan_err, tilt_err = math.degrees(det.pan_error), math.degrees(det.tilt_error)
        head = self.tracker.update(det.found, pan_err, tilt_err, now, dt)
        self._head_goal = (math.radians(head.pan), math.radians(head.tilt))
        if head.gave_up:
            self._finish("lost", "ball play gave up: no ball found", walk)
            return
        pan, tilt = (math.degrees(float(frame.position[j])) for j in HEAD)
        if head.searching:
            # Turn in place while the head sweeps, once a sweep alone found nothing.
            self.follower.reset()
            if head.turn:
                walk.walk(0.0, head.turn)
            else:
                walk.stop()
            self._set_phase("searching", "lost sight of the ball: searching")
            return
        cmd = self.follower.update(det.found, tilt_err, pan, tilt, pan_err)
        if cmd.kick and self.frames > _SETTLE_FRAMES:
            self._kick_side = cmd.kick
            self._set_phase("kicking", f"kicking with the {_foot(cmd.kick)} foot")
            walk.stop()
            self._kick_started = self._walk_stopped = None
            return
        if cmd.walk:
            walk.walk(cmd.step, cmd.turn)
            moving_on = cmd.step > 0 or self.follower.goal_step > 0
            if det.found:
                self._set_phase(
                    "approaching" if moving_on else "tracking",
                    "walking to the ball" if moving_on else "turning to the ball",
                )
        else:
            walk.stop()
            if det.found:
                self._set_phase("tracking", "ball ahead: lining up")

    def _kick_tick(self, frame: JointFrame, walk: WalkPort) -> None:
        action = self.manager.get("action") if self.manager else None
        if action is None:
            self._finish("stopped", "cannot kick: no action module", walk)
            return
        f = self.settings.follower
        if self._kick_started is None:
            if walk.running():
                walk.stop()  # the walk ends its step first
                self._walk_stopped = None
                return
            if self._walk_stopped is None:
                self._walk_stopped = frame.time
            if frame.time - self._walk_stopped < f.kick_settle_s:
                return  # the body still sways from the last step: the page starts from rest
            page = f.left_kick_page if self._kick_side > 0 else f.right_kick_page
            self._kick_playing = True  # before play(): it takes the head, on_released gives it back
            try:
                action.play(page)  # type: ignore[attr-defined]  # the action player's
            except KeyError:
                self._kick_playing = False
                self._finish("stopped", f"cannot kick: no action page {page}", walk)
                return
            self._kick_started = frame.time
            return
        playing = bool(getattr(action, "playing", False))
        if playing and frame.time - self._kick_started < f.kick_timeout_s:
            return
        self.kicks += 1
        self._kick_playing = False
        self.emit("ballplay", f"kick {self.kicks} done", phase="kicking", kicks=self.kicks)
        if self.settings.kicks and self.kicks >= self.settings.kicks:
            self._finish("done", f"ball play done after {self.kicks} kick(s)", walk)
            return
        self.follower.reset()
        self._last_frame_time = None
        with self._slot_lock:
            self._slot = None
        self._set_phase("tracking", "kicked: looking for the ball again")

    def _head_goals(self, frame: JointFrame) -> dict[int, float]:
        if self._head_goal is None:
            self._head_cmd = None
            return {}
        if self._head_cmd is None:
            self._head_cmd = [float(frame.position[j]) for j in HEAD]
        # The commanded head moves at a bounded speed towards the tracker's goal.
        step = math.radians(self.settings.head.max_speed_dps) * frame.dt
        for k, goal in enumerate(self._head_goal):
            now = self._head_cmd[k]
            self._head_cmd[k] = now + max(-step, min(step, goal - now))
        return dict(zip(HEAD, self._head_cmd, strict=True))

    # -- phases ----------------------------------------------------------------------------
    def _set_phase(self, phase: str, message: str) -> None:
        if phase != self.phase:
            self.phase = phase
            self.emit("ballplay", message, phase=phase, kicks=self.kicks)

    def _finish(self, phase: str, message: str, walk: WalkPort | None = None) -> None:
        (walk or WalkPort.of(self.manager)).stop()
        self._head_goal = None
        self.release(HEAD)
        self._set_phase(phase, message)

    def status(self) -> dict[str, Any]:
        last = self.last
        return {
            "active": self.active,
            "phase": self.phase,
            "color": self.color,
            "kicks": self.kicks,
            "frames": self.frames,
            "ball": (
                {"found": last.found, "pan": last.pan_error, "tilt": last.tilt_error}
                if last is not None
                else None
            ),
            "walk": {"step_mm": self.follower.step, "turn_deg": self.follower.turn},
        }


def _foot(side: int) -> str:
    return "left" if side > 0 else "right"
