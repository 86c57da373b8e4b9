"""Fall detection from the accelerometer (the framework's rule) and recovery.

The mean of the last ``fall_window`` (30) accel Y samples (the CM-730 register; the robot's
fore/aft axis, ``JointFrame.accel_raw[0]``) below ``fall_forward_below`` (390)
means fallen forward, above ``fall_backward_above`` (580) fallen backward ([imu] config). Ours,
not the framework's: only samples whose accel Z (the up axis) is below ``fall_lying_z_below``
(590; upright reads 512 + 1 g = 640, lying 512) count, and an upright sample empties the window.
A shove accelerates an upright body along its fore/aft axis for longer than the window (the
MuJoCo plant: 40 N for 0.2 s reads accel Y ~250 while the body is still upright), and on the
framework's rule alone the detector latched the wrong direction before the robot landed on the
other side. Ours too: a fall is called only when the present reading is gravity (within
``fall_gravity_band``, 0.3, of 1 g) on the side the window says, so a tumbling or landing body's
readings in the window cannot call the side it does not lie on.
As the framework (``MotionManager::Process``), falls are computed only once the gyro is
calibrated (``frame.imu_calibrated``, motion/gyro_centre.py), only error-free CM-730 readings
enter the window (``frame.imu_valid``: before the CM-730 first answered the block is zeros, which
read as lying face down), and the window starts full of the neutral 512, so one bad sample
cannot make a fall. A fall
stops every module (walking, behaviours) and publishes an event. It plays the matching get-up
page (10 front, 11 back) only inside a lease holder's motion, as the motion-authority rule
(robot_daemon/motion_authority.py) has it: ``[fall] recover`` on, the lease held, and a walk,
ball play, a behaviour or the policy loop running within ``client_motion_s`` before the fall
(the policy stops itself when the body tilts, before the robot lies). Never after a halt or a
power or port event (each halts every module and clears that memory), nor at start-up: a robot
lying when the daemon starts, laid down after a halt, or falling with nobody's motion running
lies still, and the fall event says why. ROBOTIS's demo gets up likewise only in its soccer
mode, after START (``Linux/project/demo/StatusCheck.cpp``). While that page plays the robot is not
"upright again", whatever the accelerometer reads: sitting up on the way reads upright for longer
than ``settle_ticks``, and lying back on the way (page 11 rocks onto its back) then read as a new
fall that restarted the page from step 1, in a loop (the MuJoCo plant, issue 18). The ROBOTIS
framework does the same: its demo's StatusCheck::Check (Linux/project/demo/StatusCheck.cpp)
starts page 10/11 and waits while ``Action::IsRunning()`` before it reads ``FALLEN`` again.

This is the daemon's one fall detector: ``imu.fall`` is its classification of the present window
and every ``fall`` event comes from it, always with the same data::

    {"state": "fallen_forward" | "fallen_backward" | "upright",
     "direction": "forward" | "backward" | "none",
     "recovering": bool, "page": int | None}

One event when the robot falls, one when it has been upright for ``settle_ticks`` again.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

from config.loader import section_to
from robot_daemon.frames import JointFrame
from robot_daemon.motion.interface import MotionModule
from robot_daemon.motion_authority import (
    BY_NAME,
    MOVE_FALL_RECOVERY,
    RECOVERS_FROM_FALLS,
    RECOVERS_FROM_FALLS_WORDS,
)
from schemas.units import ACCEL_G_PER_COUNT, IMU_CENTER

UPRIGHT, FORWARD, BACKWARD = "upright", "fallen_forward", "fallen_backward"
# The state's word in ``imu.fall`` and the event's ``direction``.
DIRECTION = {UPRIGHT: "none", FORWARD: "forward", BACKWARD: "backward"}


@dataclass(frozen=True)
class FallRecovery:
    """``[fall]`` (config/motion.toml); the detection thresholds are in ``[imu]``."""

    recover: bool = True
    get_up_front_page: int = 10
    get_up_back_page: int = 11
    settle_ticks: int = 60
    # s: a fall counts as inside the lease holder's motion when that motion ran this recently
    # (the policy loop stops itself at a 32° tilt, a moment before the robot lies).
    client_motion_s: float = 2.0


class FallMonitor(MotionModule):
    name = "fall"

    def __init__(self, imu: dict[str, Any] | None = None, fall: dict[str, Any] | None = None):
        super().__init__()
        imu = imu or {}
        self.forward_below = float(imu.get("fall_forward_below", 390))
        self.backward_above = float(imu.get("fall_backward_above", 580))
        self.lying_z_below = float(imu.get("fall_lying_z_below", 590))
        self.gravity_band = float(imu.get("fall_gravity_band", 0.3))
        self.window: deque[float] = deque(maxlen=int(imu.get("fall_window", 30)))
        self._at_neutral = False
        self._neutral()
        settings = section_to(FallRecovery, fall or {}, "fall")
        self.recover = settings.recover
        self.front_page = settings.get_up_front_page
        self.back_page = settings.get_up_back_page
        self.settle_ticks = settings.settle_ticks
        self.client_motion_s = settings.client_motion_s
        self._client_motion_at: float | None = None  # when a lease holder's motion last ran
        self.state = UPRIGHT
        self.now = UPRIGHT  # the present window's classification (state latches until settled)
        self.falls = 0
        self._upright_ticks = 0
        self._get_up: int | None = None  # the get-up page this detector started, while it plays

    @property
    def direction(self) -> str:
        """The present window's classification as ``imu.fall`` says it."""
        return DIRECTION[self.now]

    def _neutral(self) -> None:
        if self._at_neutral:
            return  # already refilled: an upright robot costs nothing per tick
        self.window.clear()
        self.window.extend([float(IMU_CENTER)] * (self.window.maxlen or 1))
        self._at_neutral = True

    def classify(self) -> str:
        mean = sum(self.window) / len(self.window)
        if mean < self.forward_below:
            return FORWARD
        if mean > self.backward_above:
            return BACKWARD
        return UPRIGHT

    def observe(self, frame: JointFrame) -> None:
        # The framework's "accel Y" register is the robot's fore/aft axis, which JointFrame
        # holds first (robot axes x y z; see IMU_ACCEL_AXES in bus/tables.py).
        self._note_client_motion(frame)
        if not frame.imu_calibrated:
            return  # the framework computes no fall before the gyro centre is measured
        if not frame.imu_valid:
            pass  # a stale or absent CM-730 reading: the window keeps what it had
        elif float(frame.accel_raw[2]) >= self.lying_z_below:
            self._neutral()  # gravity along the up axis: upright, whatever shoves it
        else:
            self.window.append(float(frame.accel_raw[0]))
            self._at_neutral = False
        now = self.now = self.classify()
        if now != UPRIGHT and self.state == UPRIGHT and not self._lies(now, frame):
            now = self.now = UPRIGHT  # not yet: see _lies
        if self._getting_up():
            self._upright_ticks = 0
            return
        if now == UPRIGHT:
            self._upright_ticks += 1
            if self.state != UPRIGHT and self._upright_ticks >= self.settle_ticks:
                self.state = UPRIGHT
                self._event("upright again", UPRIGHT, recovering=False, page=None)
            return
        self._upright_ticks = 0
        if self.state != UPRIGHT:
            return
        self.state = now
        self.falls += 1
        self._on_fall(now, frame)

    def _lies(self, state: str, frame: JointFrame) -> bool:
        """Whether the body now lies the way the window says: the present reading is gravity
        (about 1 g, within ``fall_gravity_band``) and points that way. The window's mean can
        carry a shove's or a landing's acceleration (an 80 N forward shove read as a backward
        fall in 3 of 3 lock-step tries), and the get-up page for the wrong side would fold the
        robot against the floor; so a fall is called only once a reading at rest agrees."""
        if not frame.imu_valid:
            return False
        x, y, z = (float(v) - IMU_CENTER for v in frame.accel_raw)
        g = math.sqrt(x * x + y * y + z * z) * ACCEL_G_PER_COUNT
        if abs(g - 1.0) > self.gravity_band:
            return False
        return x < 0.0 if state == FORWARD else x > 0.0

    def _note_client_motion(self, frame: JointFrame) -> None:
        manager = self.manager
        if manager is None or manager.controller is None:
            self._client_motion_at = None  # nobody holds the lease: nobody's motion runs
            return
        for name in RECOVERS_FROM_FALLS:
            m = manager.get(name)
            if m is not None and m.in_motion:
                self._client_motion_at = frame.time
                return

    def _no_recovery(self, frame: JointFrame) -> str | None:
        """Why this fall gets no get-up page (None: it does)."""
        if not self.recover:
            return "[fall] recover is off"
        assert self.manager is not None
        if self.manager.controller is None:
            return "nobody holds the lease"
        at = self._client_motion_at
        if at is None or frame.time - at > self.client_motion_s:
            return f"no {RECOVERS_FROM_FALLS_WORDS} of the lease holder was running"
        return None

    def _getting_up(self) -> bool:
        if self._get_up is None or self.manager is None:
            return False
        action = self.manager.get("action")
        status = action.status() if action is not None else {}
        if status.get("playing") and status.get("page") in (self._get_up, None):
            return True  # None: play() accepted the page, it starts at the next tick
        self._get_up = None
        return False

    def halt(self) -> None:
        # A halt (and a power or port event, which halts too) ends the holder's motion: a fall
        # after it is nobody's to get up from.
        self._get_up = None
        self._client_motion_at = None

    def _on_fall(self, state: str, frame: JointFrame) -> None:
        manager = self.manager
        assert manager is not None
        why = self._no_recovery(frame)
        # Everything that moves the body stops now (walking, behaviours, ball play); the head
        # may keep its pose, and the action player is about to get up, or stops too.
        keep = ("action", "head") if why is None else ("head",)
        for m in manager.modules:
            if m is not self and m.name not in keep:
                m.halt()
                if m.name == "action":
                    m.release()  # its last goals are held (the walk-ready page, a kick …)
        page = self.front_page if state == FORWARD else self.back_page
        action = manager.get("action")
        recovering = False
        if why is None and action is not None:
            try:
                action.play(page)  # type: ignore[attr-defined]  # the action player's
                recovering = True
                self._get_up = page
            except (KeyError, ValueError) as exc:
                why = f"page {page} cannot be played: {exc}"
        self._client_motion_at = None  # whatever ran has been stopped
        if recovering:
            off = BY_NAME[MOVE_FALL_RECOVERY].off
            message = (
                f"fell {DIRECTION[state]}; motion stopped, getting up (page {page}; off: {off})"
            )
        else:
            message = (
                f"fell {DIRECTION[state]}; motion stopped; lying still, not getting up: {why} "
                f"(a get-up page plays by itself only inside a lease holder's "
                f"{RECOVERS_FROM_FALLS_WORDS}; to get up, play page {page})"
            )
        self._event(message, state, recovering=recovering, page=page if recovering else None)

    def _event(self, message: str, state: str, *, recovering: bool, page: int | None) -> None:
        self.emit(
            "fall",
            message,
            state=state,
            direction=DIRECTION[state],
            recovering=recovering,
            page=page,
        )

    def status(self) -> dict[str, Any]:
        return {"active": False, "state": self.state, "falls": self.falls, "recover": self.recover}
