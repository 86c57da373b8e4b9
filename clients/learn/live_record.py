"""``darwin record --lerobot DIR``: a LeRobotDataset v3 from a live robot's policy stream.

Each frame is one of the daemon's policy observations (``…/policy/obs``, published at the policy
rate, or at ``[policy] observe_hz`` while no stream runs), taken at the dataset's ``fps`` on the
daemon's clock. Its action is, in the contract's offset units ((target − default pose) / scale):

* while a policy stream runs (``obs.running``): the action the daemon applied in answer to that
  observation (``…/policy/action`` names the observation's tick, ``…/policy/applied`` what was
  written after clipping, LeRobot's convention);
* otherwise — a person drives (walk, teleop, a page) or the robot stands — the joint positions
  the next observation reports, and the frame is flagged ``takeover``.

Episodes: a line on the recorder's standard input (Enter) or the ``episode`` op on
``darwin/<robot>/record/control`` ends the open episode and starts the next, optionally with a
new task; Ctrl-C/SIGTERM ends the last. Every episode is durable when it ends
(:mod:`clients.learn.dataset`), so a kill loses at most the open one. With a camera, each frame
carries the newest JPEG from ``…/camera/jpeg`` (``observation.images.<camera>``, an mp4 per
episode).
"""

from __future__ import annotations

import contextlib
import queue
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zenoh

from clients.learn.dataset import LeRobotWriter
from schemas.errors import ErrorCode, InvalidCommandError, ProtocolError, brief
from schemas.keys import Keys
from schemas.messages import CameraFrame, decode
from schemas.policy import (
    DEFAULT_POSE,
    DEFAULT_SCALE,
    PolicyAction,
    PolicyApplied,
    PolicyObservation,
)
from schemas.query import serve

CAMERA = "head_camera"
# A policy frame whose answer has not come after this many newer observations never will (the
# action was refused, overtaken in the mailbox or lost): it takes the next positions instead.
ANSWER_WINDOW = 3
_MAX_TRACKED = 512  # actions and answers kept for pairing (a few seconds at any policy rate)
# Publications waiting for the worker (about 20 s of a 125 Hz stream): a disk or encoder that
# cannot keep up loses publications, counted and said once, rather than memory without bound.
MAX_BACKLOG = 8192


@dataclass
class _Frame:
    """One policy observation waiting for its action, with its camera image."""

    obs: PolicyObservation
    image: bytes | None
    action: list[float] | None = None
    newer: int = 0  # observations seen since this one


@dataclass
class RecordStats:
    """What a live recording wrote and what it lost."""

    episodes: int = 0
    frames: int = 0
    takeover_frames: int = 0
    observations: int = 0
    dropped: int = 0  # publications the worker could not take (MAX_BACKLOG)

    def summary(self, root: Path) -> str:
        lost = f"; {self.dropped} publications dropped" if self.dropped else ""
        return (
            f"wrote {self.episodes} episode(s), {self.frames} frames "
            f"({self.takeover_frames} takeover) to {root}{lost}"
        )


def to_action(target_rad: list[float], scale: float) -> list[float]:
    """Joint targets (rad) in the contract's offset units."""
    return [(t - d) / scale for t, d in zip(target_rad, DEFAULT_POSE, strict=True)]


class LiveRecorder:
    """Subscribes, pairs observations with what answered them, and feeds a
    :class:`LeRobotWriter` from one worker thread (Zenoh's callbacks only queue)."""

    def __init__(
        self,
        session: zenoh.Session,
        keys: Keys,
        root: str | Path,
        fps: float = 50.0,
        task: str = "",
        camera: bool = True,
        scale: float = DEFAULT_SCALE,
        on_notice: Callable[[str], None] | None = None,
    ) -> None:
        if not 1.0 <= fps <= 125.0:
            raise ValueError(f"--fps {fps} must be within 1..125 (the policy loop's rates)")
        self.session, self.keys, self.root = session, keys, Path(root)
        self.period = 1.0 / fps
        self.task, self.scale, self.camera = task, scale, camera
        self.writer = LeRobotWriter(self.root, fps, camera=CAMERA if camera else None)
        self.stats = RecordStats()
        self.notice = on_notice or (lambda line: None)
        self._events: queue.Queue[tuple[str, Any]] = queue.Queue(MAX_BACKLOG)
        self._pending: deque[_Frame] = deque()
        self._by_tick: dict[int, _Frame] = {}
        self._obs_tick_of: dict[int, int] = {}  # action seq → the observation it answers
        self._answers: dict[int, PolicyApplied] = {}  # seq → applied, before its action came
        self._early: dict[int, list[float]] = {}  # obs tick → action, before its observation
        self._next_stamp: float | None = None
        self._image: bytes | None = None
        self._first_image = threading.Event()
        self._lock = threading.Lock()  # the counters the control op reads
        self._worker = threading.Thread(target=self._run, name="lerobot-record", daemon=True)
        self._subs: list[Any] = []
        self._control: Any = None
        self._last_error = ""

    # -- lifecycle --------------------------------------------------------------------------
    def start(self, image_wait: float = 3.0) -> LiveRecorder:
        s, k = self.session, self.keys
        self._subs = [
            s.declare_subscriber(k.policy("obs"), lambda x: self._queue("obs", x)),
            s.declare_subscriber(k.policy("action"), lambda x: self._queue("action", x)),
            s.declare_subscriber(k.policy("applied"), lambda x: self._queue("applied", x)),
        ]
        if self.camera:
            self._subs.append(s.declare_subscriber(k.camera_jpeg, self._on_image))
            if not self._first_image.wait(image_wait):
                self.camera = False
                self.writer.camera = None
                self.notice(
                    f"no camera image on {k.camera_jpeg} within {image_wait:g} s: recording "
                    "state and action only (start the daemon with a camera, or pass --no-camera)"
                )
        self._control = serve(
            s, k.record_control, self._on_control, what="record", empty={"op": "status"}
        )
        self._worker.start()
        return self

    def new_episode(self, task: str | None = None, timeout: float = 10.0) -> dict[str, Any]:
        """End the open episode (written before this returns) and start the next."""
        done: queue.Queue[dict[str, Any]] = queue.Queue()
        self._events.put(("episode", (task, done)), timeout=timeout)
        return done.get(timeout=timeout)

    def stop(self) -> RecordStats:
        for x in (*self._subs, self._control):
            with contextlib.suppress(Exception):
                x.undeclare()
        self._events.put(("stop", None))  # blocks while full: the worker is draining it
        self._worker.join()
        return self.stats

    # -- Zenoh's threads --------------------------------------------------------------------
    def _queue(self, what: str, sample: zenoh.Sample) -> None:
        try:
            self._events.put_nowait((what, sample.payload.to_bytes()))
        except queue.Full:
            with self._lock:
                self.stats.dropped += 1
                first = self.stats.dropped == 1
            if first:
                self.notice(
                    f"the recorder cannot keep up with {self.keys.robot}'s policy stream: "
                    "publications are being dropped (a slower --fps, --no-camera or a faster "
                    "disk helps)"
                )

    def _on_image(self, sample: zenoh.Sample) -> None:
        # The newest image is all a frame takes: no queue, so a slow disk never backs up video.
        try:
            frame = decode(sample.payload.to_bytes(), CameraFrame)
        except ProtocolError:
            return
        assert isinstance(frame, CameraFrame)
        self._image = frame.jpeg
        self._first_image.set()

    def _on_control(self, req: dict[str, Any]) -> dict[str, Any]:
        op = req.get("op", "status")
        if op == "status":
            with self._lock:
                return {"episodes": self.stats.episodes, "frames": self.stats.frames,
                        "open_frames": self.writer.open_frames, "task": self.task,
                        "root": str(self.root)}  # fmt: skip
        if op == "episode":
            task = req.get("task")
            if task is not None and (not isinstance(task, str) or len(task) > 200):
                raise InvalidCommandError(
                    ErrorCode.INVALID, "task must be a string of at most 200 characters", "task"
                )
            return self.new_episode(task)
        raise InvalidCommandError(
            ErrorCode.INVALID, f"unknown op {brief(op)}; use episode (task) or status", "op"
        )

    # -- the worker -------------------------------------------------------------------------
    def _run(self) -> None:
        while True:
            what, data = self._events.get()
            try:
                if what == "stop":
                    self._end_episode()
                    return
                if what == "episode":
                    task, done = data
                    done.put(self._end_episode(task))
                else:
                    self._handle(what, data)
            except ProtocolError:
                continue  # a malformed publication is nobody's frame
            except Exception as exc:  # the disk: say so and keep the episodes already written
                line = f"cannot write {self.root}: {exc}"
                if line != self._last_error:  # once per cause, not once per frame
                    self.notice(line)
                self._last_error = line

    def _handle(self, what: str, payload: bytes) -> None:
        if what == "obs":
            self._on_obs(PolicyObservation.parse(payload))
        elif what == "action":
            action = PolicyAction.parse(payload)
            self._remember(self._obs_tick_of, action.seq, action.obs_tick)
            if action.seq in self._answers:
                self._answered(self._answers.pop(action.seq))
        else:
            msg = decode(payload, PolicyApplied)
            assert isinstance(msg, PolicyApplied)
            if not msg.refused:
                if msg.seq in self._obs_tick_of:
                    self._answered(msg)
                else:
                    self._remember(self._answers, msg.seq, msg)
        self._flush()

    @staticmethod
    def _remember(table: dict[int, Any], key: int, value: Any) -> None:
        table[key] = value
        if len(table) > _MAX_TRACKED:
            table.pop(next(iter(table)))

    def _answered(self, applied: PolicyApplied) -> None:
        tick = self._obs_tick_of[applied.seq]
        action = to_action(applied.target, self.scale)
        frame = self._by_tick.get(tick)
        if frame is None:
            # Publications on different keys may be delivered out of order: the answer can
            # come before the observation it answers.
            self._remember(self._early, tick, action)
        elif frame.action is None:
            frame.action = action

    def _on_obs(self, obs: PolicyObservation) -> None:
        self.stats.observations += 1
        position = [p / self.scale for p in obs.joint_pos]  # joint_pos is from the default pose
        for frame in self._pending:
            frame.newer += 1
            if frame.action is None and (not frame.obs.running or frame.newer >= ANSWER_WINDOW):
                frame.action = position
        due = self._next_stamp
        if due is None or obs.stamp >= due - 0.25 * self.period:
            # On the daemon's clock; after a gap (a restart, a stalled link) start again from now.
            restart = due is None or obs.stamp > due + self.period
            self._next_stamp = (obs.stamp if due is None or restart else due) + self.period
            frame = _Frame(obs, self._image if self.camera else None)
            frame.action = self._early.pop(obs.tick, None)
            self._pending.append(frame)
            self._by_tick[obs.tick] = frame

    def _flush(self, everything: bool = False) -> None:
        while self._pending and (everything or self._pending[0].action is not None):
            frame = self._pending.popleft()
            self._by_tick.pop(frame.obs.tick, None)
            action = frame.action
            if action is None:  # the episode ends before anything answered: hold where it is
                action = [p / self.scale for p in frame.obs.joint_pos]
            takeover = not frame.obs.running
            if self.camera and frame.image is None:
                frame.image = self._image
            self.writer.add_frame(frame.obs.vector(), action, self.task, takeover, frame.image)
            with self._lock:
                self.stats.frames += 1
                self.stats.takeover_frames += takeover

    def _end_episode(self, task: str | None = None) -> dict[str, Any]:
        self._flush(everything=True)
        index = self.writer.end_episode()
        with self._lock:
            if index >= 0:
                self.stats.episodes += 1
            if task is not None:
                self.task = task
        if index >= 0:
            self.notice(f"episode {index} written ({self.writer.episodes[-1]['length']} frames)")
        return {"ended": index, "episode": len(self.writer.episodes), "task": self.task}
