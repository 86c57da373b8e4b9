"""The omnidirectional gait of the ROBOTIS framework (Walking.cpp), as a motion module.

A clock advances one tick at a time and wraps at the period T. The left foot swings from
(1−SSP)·T/4 to (1+SSP)·T/4, the right half a period later (SSP = 1 − dsp_ratio), along
half-cosines in x, y and yaw, lifting along a raised cosine to ``foot_height``; the body sways
sideways (period T), fore/aft and up/down (period T/2). Commanded amplitudes are latched only at
mid-swing, moving toward the command by at most ``accel_*`` per step. Stopping zeroes the
command at the next step boundary, so walking ends at the end of a step.

Commands in SI map to the framework's amplitudes (T in s):
  X [mm] = x [m/s] · T · 1000 / 4   (the body advances 2·X per step, 4·X per cycle)
  Y [mm] = y [m/s] · T · 1000 / 2   (the body moves Y per step)
  A [°]  = turn [rad/s] · T / 2 in degrees (the body turns A per step)
"""

from __future__ import annotations

import math
from typing import Any, cast

import numpy as np

from robot_daemon.frames import JointFrame
from robot_daemon.hotpath import compiled as _compiled
from robot_daemon.motion.interface import MotionModule
from robot_daemon.motion.walking.balance import FEEDBACK_SIGNS, gyro_feedback
from robot_daemon.motion.walking.ik import LEG_SERVOS, leg_servo_angles
from robot_daemon.motion.walking.params import WalkParams
from robot_daemon.motion.walking.ready import PagePlayer, WalkReady
from schemas.units import RAD_PER_UNIT

LEG_IDS = tuple(range(7, 19))
# The walk owns all six arm servos, as ROBOTIS's demo enables the walk on the whole body but the
# head (SetEnableBodyWithoutHead): the shoulder pitches swing, the shoulder rolls and elbows
# hold the walk's arm pose, and all six run soft (Walking.cpp's constructor: these angles, and
# SetPGain(…, 8) on ID_R/L_SHOULDER_PITCH, _SHOULDER_ROLL and _ELBOW).
ARM_IDS = (1, 2, 3, 4, 5, 6)
WALK_IDS = (*ARM_IDS, *LEG_IDS)
ARM_INIT_DEG = {1: -48.345, 2: 41.313, 3: -17.873, 4: 17.580, 5: 29.300, 6: -29.593}
ARM_P_GAIN = 8  # the framework's arms while walking
ARM_INIT_RAD = {j: math.radians(d) for j, d in ARM_INIT_DEG.items()}

# _pose_py whole, compiled (robot_daemon/hotpath.py; the same goals to the bit and in the same
# key order, tests/unit/test_hotpath.py), given the constants above; None without it.
_walk_pose = None
if _compiled is not None and _compiled.configure_walk(
    *LEG_SERVOS["right"], *LEG_SERVOS["left"], ARM_INIT_DEG[1], ARM_INIT_DEG[2],
    tuple(ARM_INIT_RAD[j] for j in (3, 4, 5, 6)), FEEDBACK_SIGNS, math.radians(1.0),
    RAD_PER_UNIT,
):
    _walk_pose = _compiled.walk_pose


def _wsin(t: float, period: float, shift: float, mag: float, mag_shift: float) -> float:
    return mag * math.sin(2 * math.pi / period * t - shift) + mag_shift


def amplitudes_from_si(x: float, y: float, turn: float, period_ms: float) -> tuple[float, ...]:
    """(X mm, Y mm, A deg) for speeds x, y (m/s) and turn (rad/s)."""
    t = period_ms / 1000.0
    return (x * t * 1000 / 4, y * t * 1000 / 2, math.degrees(turn * t / 2))


def si_from_amplitudes(
    x_mm: float, y_mm: float, a_deg: float, period_ms: float
) -> tuple[float, float, float]:
    t = period_ms / 1000.0
    return (x_mm * 4 / 1000 / t, y_mm * 2 / 1000 / t, math.radians(a_deg) * 2 / t)


class WalkingModule(MotionModule):
    name = "walking"
    claim_ids = WALK_IDS

    def __init__(self, params: WalkParams | None = None) -> None:
        super().__init__()
        self.params = params or WalkParams()
        self.cmd = [0.0, 0.0, 0.0]  # commanded X mm, Y mm, A deg
        self.latched = [0.0, 0.0, 0.0]  # amplitudes in use
        self.ctrl_running = False
        self.running = False
        self.time_ms = 0.0
        self.steps = 0
        self.skipped = 0
        self._ready_t: float | None = None  # s left in the blend into the stance
        # The gyro centre, then the walk-ready page (walking/ready.py), before the gait runs.
        self.ready = WalkReady(self._player, self._ids)
        self._ready_from: dict[int, float] = {}
        self._next_phase = 1  # the phase point (1, 2, 3) this period has not reached yet
        self._wrapped = False  # the period just ended: the next tick starts the new one
        self._last: dict[int, float] = {}
        self._limits: dict[int, tuple[float, float]] | None = None
        self._gyro_f = [0.0, 0.0]  # low-passed gyro counts (right/left, front/back)
        self._gains: dict[int, tuple[int, int, int]] = {}
        self._gains_for: tuple[int, int, int] | None = None
        # ``halt`` during the gait: the walk runs on to its next step boundary, the middle of
        # a double support with both feet down, and stops there (at most half a period).
        self._halting = False
        self._update_time()
        self._update_move()

    # -- commands --------------------------------------------------------------------------------
    def start(
        self, x: float | None = None, y: float | None = None, turn: float | None = None
    ) -> tuple[float, ...]:
        """Start (or keep) walking; with speeds x, y (m/s) and turn (rad/s) also set them (else
        the last command stands). Returns the (X mm, Y mm, A deg) command."""
        if x is not None or y is not None or turn is not None:
            self.set_speed(x or 0.0, y or 0.0, turn or 0.0)
        if not self.running:
            if not self.ready.begin():  # no action player: the gait takes the legs now
                self.claim(WALK_IDS)
            self.running = True
            self._halting = False
            self.steps = 0  # the status's and the events' count is this walk's
            self.time_ms = 0.0
            self.latched = [0.0, 0.0, 0.0]
            self._update_time()
            self._ready_t = self.params.ready_time
            self._ready_from = {}
            self.emit("walk", "walking started", state="started")
        self.ctrl_running = True
        self._halting = False  # a walk started again after a halt walks on
        return tuple(self.cmd)

    def set_speed(self, x: float, y: float, turn: float) -> tuple[float, ...]:
        """Command speeds x, y (m/s) and turn (rad/s); see the module docstring for units."""
        return self.set_amplitudes(*amplitudes_from_si(x, y, turn, self.params.period_time))

    def set_amplitudes(self, x: float, y: float, turn: float) -> tuple[float, ...]:
        """Command the framework's amplitudes: X, Y in mm, turn A in degrees (per step),
        clamped to the configured maxima."""
        p = self.params
        xa, ya, aa = x, y, turn
        self.cmd = [
            max(-p.max_x, min(p.max_x, xa)),
            max(-p.max_y, min(p.max_y, ya)),
            max(-p.max_turn, min(p.max_turn, aa)),
        ]
        return tuple(self.cmd)

    def stop(self) -> None:
        """Finish the current step and stand."""
        self.ctrl_running = False

    def halt_safely(self) -> None:
        """The ``halt`` verb (``MOVE_WALK_LAST_STEP``, robot_daemon/motion_authority.py).
        Stopped at once, a walk would stand on one foot for most of a period (the swing foot
        up to the step height in the air, the body over the stance foot) and tip over. So
        while the gait runs it ends at its next step boundary (time 0 or phase 2 of the
        period: the middle of a double support, both feet down, the body centred), at most
        half a period later, and holds there; ROBOTIS's Walking.cpp stops only there too
        (``m_Real_Running = false`` at those two phase points). Before the gait runs (gyro,
        walk-ready page, the blend into the stance) both feet are down: it stops at once."""
        if self.running and not self.ready.state and self._ready_t is None and self.owned():
            self.ctrl_running = False
            self.cmd = [0.0, 0.0, 0.0]
            self._halting = True
            return
        self.halt()

    @property
    def finishing(self) -> bool:
        return self._halting and self.running

    @property
    def in_motion(self) -> bool:
        return self.running and not self._halting

    @property
    def sequencing(self) -> bool:
        return bool(self.ready.state)  # the walk-ready page plays for it

    def halt(self) -> None:
        self._halting = False
        self.ready.cancel()
        self.ctrl_running = self.running = False
        self.cmd = [0.0, 0.0, 0.0]
        self.latched = [0.0, 0.0, 0.0]
        self._ready_t = None

    def on_released(self, ids: set[int]) -> None:
        if self.running and set(LEG_IDS) & ids:
            self.halt()
            self.emit("walk", "walking interrupted: another module took the legs", state="stopped")

    @property
    def walking(self) -> bool:
        return self.running

    @property
    def active(self) -> bool:
        # Waiting for the gyro or the walk-ready page it owns nothing yet, but it is running:
        # a lease that ends (stop_all) or a fall must stop it before it takes the legs.
        return self.running or bool(self.owned())

    # -- before the gait: the walk-ready sequence ------------------------------------------------
    def _player(self) -> PagePlayer | None:
        # The manager hands back a MotionModule; the one named "action" is the player.
        player = self.manager.get("action") if self.manager is not None else None
        return cast("PagePlayer | None", player)

    def _ids(self) -> tuple[int, ...]:
        return self.manager.robot.ids if self.manager is not None else ()

    def observe(self, frame: JointFrame) -> None:
        if not self.ready.observe(frame, self.ctrl_running):
            return
        if self.ctrl_running and self.running:
            self.claim(self.claim_ids)
        elif self.running:
            self.running = False
            self.emit("walk", "walking stopped", state="stopped", steps=self.steps)

    # -- the framework's parameter updates -------------------------------------------------------
    def _update_time(self) -> None:
        p = self.params
        t = p.period_time
        ssp = 1.0 - p.dsp_ratio
        self.period = t
        self.ssp_start_l = (1 - ssp) * t / 4
        self.ssp_end_l = (1 + ssp) * t / 4
        self.ssp_start_r = (3 - ssp) * t / 4
        self.ssp_end_r = (3 + ssp) * t / 4
        self.x_move_period = self.y_move_period = self.a_move_period = t * ssp
        self.z_move_period = t * ssp / 2
        self.phase1 = (self.ssp_end_l + self.ssp_start_l) / 2
        self.phase2 = (self.ssp_start_r + self.ssp_end_l) / 2
        self.phase3 = (self.ssp_end_r + self.ssp_start_r) / 2

    def _update_move(self) -> None:
        """Latch the command at mid-swing (where every foot trajectory crosses zero, so the
        change is smooth), within the acceleration limits; when stopping, latch zero."""
        p = self.params
        if not self.ctrl_running:
            self.latched = [0.0, 0.0, 0.0]
            return
        for k, lim in enumerate((p.accel_x, p.accel_y, p.accel_turn)):
            delta = max(-lim, min(lim, self.cmd[k] - self.latched[k]))
            self.latched[k] += delta

    def _boundary(self) -> None:
        """A step boundary (time 0 or phase 2): stop here when asked and the feet are together
        (amplitudes zero), else take one more step, latching zero at its mid-swing."""
        self._update_time()
        self.steps += 1
        if self._halting:
            self._halting = self.running = False
            self.cmd = [0.0, 0.0, 0.0]  # this tick's pose keeps the step's amplitudes
            self.emit(
                "walk",
                "walking halted at double support; holding",
                state="stopped",
                steps=self.steps,
            )
        elif not self.ctrl_running and all(abs(a) < 1e-9 for a in self.latched):
            self.running = False
            self.cmd = [0.0, 0.0, 0.0]
            self.emit("walk", "walking stopped", state="stopped", steps=self.steps)

    # -- the tick --------------------------------------------------------------------------------
    def step(self, frame: JointFrame) -> dict[int, float]:
        if not self.running:
            if self._last and self.active:
                # Standing after a stop: hand the joints back, holding the last pose.
                self._last = {}
                self.latched = [0.0, 0.0, 0.0]
                self.release()
            return {}
        if not frame.imu_calibrated:
            return {}  # no motion before the gyro centre is measured (walking/ready.py)
        tick_ms = frame.dt * 1000.0
        if self._ready_t is not None:
            return self._blend(frame)
        self._clock(tick_ms)
        # The walk's last pose is held after it (static goals): without the gyro feedback of
        # that one tick, which frozen in the knees and ankles tipped a halted robot over.
        goals = self._pose(frame, balance=self.running)
        if self.running:
            self.time_ms += tick_ms
            if self.time_ms >= self.period - 1e-9:
                # Carry what the last tick ran past the period's end: ROBOTIS's Walking.cpp
                # resets to 0, exact only when the tick divides the period (8 ms into 600);
                # with a 16 ms tick every period would last 608 ms, a slower walk.
                self.time_ms = max(0.0, self.time_ms - self.period)
                if self.time_ms < 1e-9:
                    self.time_ms = 0.0
                self._wrapped = True
        if goals is None:
            self.skipped += 1
            return {}
        self._last = goals
        return goals

    def _clock(self, tick_ms: float) -> None:
        """Fire each phase point of the period once, at the first tick that reaches its window
        (± half a tick): with a steady period that is the tick nearest to it, as the framework
        does; after a late tick (time follows the clock) it is the next one, never skipped."""
        t, half = self.time_ms, tick_ms / 2
        if t == 0.0 or self._wrapped:
            self._wrapped = False
            self._next_phase = 1
            self._boundary()
        elif self._next_phase == 1 and t >= self.phase1 - half:
            self._next_phase = 2
            self._update_move()
        elif self._next_phase == 2 and t >= self.phase2 - half:
            self._next_phase = 3
            # Walking.cpp snaps the clock to the phase point here; with a tick that divides the
            # half period (8 ms into 300) that is a no-op, with any other (16 ms) it would move
            # the clock by up to half a tick every step and change the period: time runs on.
            self._boundary()
        elif self._next_phase == 3 and t >= self.phase3 - half:
            self._next_phase = 4
            self._update_move()

    def _blend(self, frame: JointFrame) -> dict[int, float]:
        """Move smoothly from the pose the joints hold into the gait's stance before the clock
        runs."""
        stance = self._pose(frame, balance=False)
        if stance is None:
            self.halt()
            self.emit("walk", "walking refused: the stance is out of reach", state="stopped")
            return {}
        if not self._ready_from:  # from the goals the joints hold (frames.py: start_of)
            self._ready_from = {j: frame.start_of(j) for j in stance}
        total = max(self.params.ready_time, 1e-6)
        assert self._ready_t is not None
        self._ready_t -= frame.dt
        s = min(1.0, 1.0 - self._ready_t / total) if self.params.ready_time > 0 else 1.0
        w = (1 - math.cos(math.pi * s)) / 2
        goals = {j: self._ready_from[j] + (g - self._ready_from[j]) * w for j, g in stance.items()}
        if s >= 1.0:
            self._ready_t = None
        self._last = goals
        return goals

    def _pose(self, frame: JointFrame, balance: bool = True) -> dict[int, float] | None:
        """The goals of this tick's point of the gait (None: out of reach or of the joints'
        limits), by the compiled pose where it is built, else by :meth:`_pose_py`."""
        if _walk_pose is not None:
            got = _walk_pose(self, self.params, frame, balance, self._limit_map())
            if got is not NotImplemented:
                goals, filtered = got
                if filtered is not None:
                    self._gyro_f = filtered
                return cast("dict[int, float] | None", goals)
        return self._pose_py(frame, balance)

    def _pose_py(self, frame: JointFrame, balance: bool = True) -> dict[int, float] | None:
        p, t = self.params, self.time_ms
        xm, ym_cmd, am_cmd = self.latched
        x_swap_amp = xm * p.step_forward_back_ratio
        ym = ym_cmd / 2
        y_swap_amp = p.swing_right_left + abs(ym) * 0.04
        zm = p.foot_height / 2
        am = math.radians(am_cmd) / 2
        x_swap = _wsin(t, self.period / 2, math.pi, x_swap_amp, 0)
        y_swap = _wsin(t, self.period, 0, y_swap_amp, 0)
        z_swap = _wsin(t, self.period / 2, math.pi * 3 / 2, p.swing_top_down, p.swing_top_down)

        # Left foot swings in [start_l, end_l], the right in [start_r, end_r]; outside its own
        # window each trajectory holds the value at the window's edge (Walking.cpp).
        sl, el, sr, er = self.ssp_start_l, self.ssp_end_l, self.ssp_start_r, self.ssp_end_r
        if t <= sl:
            txy, start, extra, zl_t, zr_t = sl, sl, 0.0, sl, sr
        elif t <= el:
            txy, start, extra, zl_t, zr_t = t, sl, 0.0, t, sr
        elif t <= sr:
            txy, start, extra, zl_t, zr_t = el, sl, 0.0, el, sr
        elif t <= er:
            txy, start, extra, zl_t, zr_t = t, sr, math.pi, el, t
        else:
            txy, start, extra, zl_t, zr_t = er, sr, math.pi, el, er
        # Walking.cpp's wsin(t, period, π/2 + 2π/period · start + extra, mag, shift) for each
        # foot's move, written out: both feet's x, y and yaw moves share one sine of one
        # phase (only their magnitude and shift differ), so six calls are three sines, in the
        # same arithmetic as _wsin (the same bits).
        sin = math.sin
        w = 2 * math.pi / self.x_move_period
        s_x = sin(w * txy - (math.pi / 2 + w * start + extra))
        w = 2 * math.pi / self.y_move_period
        s_y = sin(w * txy - (math.pi / 2 + w * start + extra))
        w = 2 * math.pi / self.a_move_period
        s_a = sin(w * txy - (math.pi / 2 + w * start + extra))
        x_l, x_r = xm * s_x + 0, -xm * s_x + 0
        y_l, y_r = ym * s_y + abs(ym), -ym * s_y + -abs(ym)
        c_l, c_r = am * s_a + abs(am), -am * s_a + -abs(am)
        w = 2 * math.pi / self.z_move_period
        z_l = zm * sin(w * zl_t - (math.pi / 2 + w * self.ssp_start_l + 0)) + zm
        z_r = zm * sin(w * zr_t - (math.pi / 2 + w * self.ssp_start_r + 0)) + zm

        pelvis = math.radians(p.pelvis_offset)
        pelvis_swing = pelvis * 0.35
        pel_l = pel_r = 0.0
        if self.ssp_start_l < t <= self.ssp_end_l:
            ph = math.pi / 2 + 2 * math.pi / self.z_move_period * self.ssp_start_l
            pel_l = _wsin(t, self.z_move_period, ph, pelvis_swing / 2, pelvis_swing / 2)
            pel_r = _wsin(t, self.z_move_period, ph, -pelvis / 2, -pelvis / 2)
        elif self.ssp_start_r < t <= self.ssp_end_r:
            ph = math.pi / 2 + 2 * math.pi / self.z_move_period * self.ssp_start_r
            pel_l = _wsin(t, self.z_move_period, ph, pelvis / 2, pelvis / 2)
            pel_r = _wsin(t, self.z_move_period, ph, -pelvis_swing / 2, -pelvis_swing / 2)

        r_off, p_off, a_off = (
            math.radians(v) for v in (p.roll_offset, p.pitch_offset, p.yaw_offset)
        )
        mm = 0.001
        right = (
            (x_swap + x_r + p.x_offset) * mm,
            (y_swap + y_r - p.y_offset / 2) * mm,
            (z_swap + z_r + p.z_offset) * mm,
            -r_off / 2,
            p_off,
            c_r - a_off / 2,
        )
        left = (
            (x_swap + x_l + p.x_offset) * mm,
            (y_swap + y_l + p.y_offset / 2) * mm,
            (z_swap + z_l + p.z_offset) * mm,
            r_off / 2,
            p_off,
            c_l + a_off / 2,
        )
        hip_pitch = math.radians(p.hip_pitch_offset)
        r_servo = leg_servo_angles("right", right, hip_pitch)
        l_servo = leg_servo_angles("left", left, hip_pitch)
        if r_servo is None or l_servo is None:
            return None
        goals = {**r_servo, **l_servo}
        goals[9] += -pel_r  # framework: dir · pelvis offset, dir = −1 on both hip rolls
        goals[10] += -pel_l
        arm = 0.0 if xm == 0 else _wsin(t, self.period, math.pi * 1.5, xm * p.arm_swing_gain, 0)
        goals[1] = math.radians(ARM_INIT_DEG[1] - arm)
        goals[2] = math.radians(ARM_INIT_DEG[2] - arm)
        for j in (3, 4, 5, 6):
            goals[j] = ARM_INIT_RAD[j]
        if balance and p.balance_enable:
            self._gyro_f = gyro_feedback(goals, frame, p, self._gyro_f)
        if not self._within_limits(goals):
            return None
        return goals

    def _limit_map(self) -> dict[int, tuple[float, float]] | None:
        """The robot's limits by joint, as JointConfig.within has them, made once (None
        without a manager: nothing to check against)."""
        if self.manager is None:
            return None
        limits = self._limits
        if limits is None:
            by_id = self.manager.robot.by_id
            limits = self._limits = {
                j: (c.min_rad - 1e-9, c.max_rad + 1e-9) for j, c in by_id.items()
            }
        return limits

    def _within_limits(self, goals: dict[int, float]) -> bool:
        limits = self._limit_map()
        if limits is None:
            return True
        for j, g in goals.items():
            lim = limits.get(j)
            if lim is not None and not lim[0] <= g <= lim[1]:
                return False
        return True

    def gains(self) -> dict[int, tuple[int, int, int]]:
        p = self.params
        pid = (p.p_gain, p.i_gain, p.d_gain)
        if self._gains_for != pid:  # made again only when the parameters change, not per tick
            # Soft arms "to protect the joints when it fell down" (ROBOTIS Walking.cpp: P = 8).
            self._gains = {
                **dict.fromkeys(LEG_IDS, pid),
                **dict.fromkeys(ARM_IDS, (ARM_P_GAIN, 0, 0)),
            }
            self._gains_for = pid
        return self._gains

    def status(self) -> dict[str, Any]:
        lx, ly, la = self.latched
        x, y, a = si_from_amplitudes(lx, ly, la, self.params.period_time)
        return {
            "active": self.active,
            "walking": self.running,
            "stopping": self.running and not self.ctrl_running,
            "command": {"x_mm": self.cmd[0], "y_mm": self.cmd[1], "turn_deg": self.cmd[2]},
            "amplitude": {
                "x_mm": self.latched[0],
                "y_mm": self.latched[1],
                "turn_deg": self.latched[2],
            },
            "speed": {"x": x, "y": y, "turn": a},
            "phase_ms": self.time_ms,
            "steps": self.steps,
            "skipped_ticks": self.skipped,
        }


def foot_heights(goals: dict[int, float], lean: float = 0.0) -> tuple[float, float]:
    """Height (m) of each sole above the lower one, from servo goals, measured in a body frame
    pitched forward by ``lean`` (rad; the gait's hip pitch offset makes the feet level)."""
    from schemas.kinematics import leg_fk, rot_y

    pos = np.zeros(21)
    for j, g in goals.items():
        pos[j] = g
    level = rot_y(lean)
    zr = (level @ leg_fk(pos, "right")[:3, 3])[2]
    zl = (level @ leg_fk(pos, "left")[:3, 3])[2]
    low = min(zr, zl)
    return zr - low, zl - low
