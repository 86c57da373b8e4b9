"""The action player: plays pages as the ROBOTIS framework does.

Each step moves every driven joint from where it is to the step's key frame in the step's time,
along a trapezoidal velocity profile (ramp ``accel`` time units, constant speed, ramp down). A
joint that keeps its direction into the next step passes through the key frame without stopping
(a via-point) unless the step pauses or is the page's last; otherwise it stops there. Pages play
``repeat`` times and chain through ``next``; ``stop`` finishes the page and plays its ``exit``
page instead; ``brake`` ends the current step at rest and stops.

Time: one time unit is 8 ms at page speed 32 (``unit = 0.008 · 32 / speed`` s). Time-based pages
(schedule 0x0A) take ``time`` units per step. Speed-based pages (schedule 0) have no time: there
``time`` is the speed of the joint that moves most, in units of 2 °/s.

Gains: a page's per-joint slope byte sets that joint's P gain while the page plays, as the
framework's Action.cpp does for the MX-28 (which has no compliance slopes): P = (256 >> (slope
>> 4)) << 2, so the default 0x55 gives 32, 0x44 64, 0x33 128, 0x77 8 (capped at the register's
254). When the page ends the joints fall back to the configured gains.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from robot_daemon.frames import JointFrame
from robot_daemon.motion.action.binfile import JOINT_SLOTS, SCHEDULE_SPEED, Page
from robot_daemon.motion.action.check import page_problems
from robot_daemon.motion.action.library import MotionLibrary
from robot_daemon.motion.action.store import PageStore
from robot_daemon.motion.interface import MotionModule
from schemas.units import raw_to_rad

TIME_UNIT_S = 0.008  # at speed 32
SPEED_BASED_DEG_S = 2.0
P_GAIN_MAX = 254  # the MX-28's P gain register


def slope_p_gain(slope: int) -> int:
    """The P gain a page's slope byte asks for: Action.cpp's ``(256 >> (slope >> 4)) << 2``
    (ROBOTIS DARwIn-OP framework, MX-28 build), capped at the register's range."""
    return min(P_GAIN_MAX, (256 >> (slope >> 4)) << 2)


@dataclass
class _Segment:
    """One step's motion for the page's joints (arrays aligned with ``ids``)."""

    x0: np.ndarray
    dist: np.ndarray
    v0: np.ndarray
    v1: np.ndarray
    vm: np.ndarray
    duration: float
    ramp: float

    @classmethod
    def plan(
        cls,
        x0: np.ndarray,
        x1: np.ndarray,
        v0: np.ndarray,
        v1: np.ndarray,
        duration: float,
        ramp: float,
    ) -> _Segment:
        duration = max(duration, 1e-6)
        ramp = min(ramp, duration / 2)
        dist = x1 - x0
        if ramp <= 0:
            vm = dist / duration
            v0 = v1 = vm
        else:
            vm = (dist - ramp * (v0 + v1) / 2) / (duration - ramp)
        return cls(x0, dist, v0, v1, vm, duration, ramp)

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity ``t`` seconds into the step."""
        a, d = self.ramp, self.duration
        t = min(max(t, 0.0), d)
        if a <= 0:
            return self.x0 + self.vm * t, self.vm.copy()
        if t < a:
            x = self.v0 * t + (self.vm - self.v0) * t * t / (2 * a)
            v = self.v0 + (self.vm - self.v0) * t / a
        elif t <= d - a:
            x = a * (self.v0 + self.vm) / 2 + self.vm * (t - a)
            v = self.vm.copy()
        else:
            tau = t - (d - a)
            x = (
                a * (self.v0 + self.vm) / 2
                + self.vm * (d - 2 * a)
                + self.vm * tau
                + (self.v1 - self.vm) * tau * tau / (2 * a)
            )
            v = self.vm + (self.v1 - self.vm) * tau / a
        if t >= d:
            x = self.dist
        return self.x0 + x, v


def page_targets(page: Page, ids: list[int], previous: np.ndarray) -> list[np.ndarray]:
    """Key frames (rad) for ``ids``; a joint a step does not drive keeps its previous target."""
    frames = []
    cur = previous.copy()
    for step in page.steps:
        cur = cur.copy()
        for k, jid in enumerate(ids):
            if step.driven(jid):
                cur[k] = float(raw_to_rad(step.words[jid]))
        frames.append(cur)
    return frames


def page_joints(page: Page) -> list[int]:
    return [j for j in JOINT_SLOTS if any(s.driven(j) for s in page.steps)]


class ActionModule(MotionModule):
    name = "action"

    def __init__(self, library: MotionLibrary, store: PageStore | None = None) -> None:
        super().__init__()
        self.library = library
        self.store = store  # where the library comes from and is saved to (``pages`` verb)
        self._page: Page | None = None
        self._ids: list[int] = []
        self._frames: list[np.ndarray] = []
        self._step = 0
        self._repeat = 0
        self._phase = "idle"  # idle | move | pause
        self._t = 0.0
        self._seg: _Segment | None = None
        self._pos = np.zeros(0)
        self._vel = np.zeros(0)
        self._pending: Page | None = None
        self._pending_step = 0
        self._entry = 0  # the step the page was entered at
        self._stopping = False
        self._braking = False
        self._only: set[int] | None = None  # play() asked for these joints only

    # -- commands (motion thread, between ticks) ------------------------------------------------
    def play(self, ref: int | str, step: int = 1, joints: set[int] | None = None) -> Page:
        """Queue a page to start on the next tick at ``step`` (1-based; later repeats start at
        1); ``KeyError`` for an unknown page or step, ``ValueError`` for a page (or a page it
        chains to) that leaves the joint limits or breaks the format's rules. ``joints``: play
        only those of the page's joints (the others keep their owner)."""
        page = self.library.page(ref)
        if not 1 <= step <= len(page.steps):
            raise KeyError(f"page {page.number} ({page.name}) has steps 1..{len(page.steps)}")
        if self.manager is not None:
            lib, robot = self.library, self.manager.robot
            bad = [
                problem
                for n in lib.chain(page.number)
                for problem in page_problems(lib.pages[n], robot, lib)
            ]
            if bad:
                raise ValueError(
                    f"page {page.number} ({page.name}) cannot be played: {bad[0]}"
                    + (f" (and {len(bad) - 1} more)" if len(bad) > 1 else "")
                )
        self._pending, self._pending_step = page, step - 1
        self._stopping = self._braking = False
        self._only = joints
        self.claim(self._playable(page_joints(page)))
        return page

    def _playable(self, ids: list[int]) -> set[int]:
        return {j for j in ids if self._only is None or j in self._only}

    def in_use(self) -> set[int]:
        """Pages playing, queued, or reachable from the one playing (through next/exit)."""
        out: set[int] = set()
        for page in (self._page, self._pending):
            if page is not None:
                out |= {page.number, *self.library.chain(page.number)}
        return out

    def stop(self) -> None:
        """Finish the current page (its repeats too), then play its exit page if it has one."""
        if self.playing:
            self._stopping = True

    def brake(self) -> None:
        """End the current step at rest, then stop."""
        if self.playing:
            self._braking = True
            if self._phase == "move" and self._seg is not None:
                remaining = self._seg.duration - self._t
                target = self._seg.x0 + self._seg.dist
                self._seg = _Segment.plan(
                    self._pos,
                    target,
                    self._vel,
                    np.zeros_like(self._vel),
                    remaining,
                    self._ramp(self._page) if self._page else 0.0,
                )
                self._t = 0.0

    def halt(self) -> None:
        self._finish("halted", release=False)
        self._pending = None

    @property
    def playing(self) -> bool:
        return self._page is not None or self._pending is not None

    # -- the tick ------------------------------------------------------------------------------
    def step(self, frame: JointFrame) -> dict[int, float]:
        if self._pending is not None:
            self._begin(self._pending, frame, self._pending_step)
            self._pending, self._pending_step = None, 0
        if self._page is None:
            return {}
        self._advance(frame.dt)
        return {j: float(self._pos[k]) for k, j in enumerate(self._ids)}

    def gains(self) -> dict[int, tuple[int, int, int]]:
        page = self._page
        if page is None or self.manager is None:
            return {}
        out: dict[int, tuple[int, int, int]] = {}
        for j in self._ids:
            cfg = self.manager.robot.by_id.get(j)
            if cfg is None or j >= len(page.slopes):
                continue
            p = slope_p_gain(page.slopes[j])
            if p != cfg.p:
                out[j] = (p, cfg.i, cfg.d)
        return out

    def _unit(self, page: Page) -> float:
        return TIME_UNIT_S * 32.0 / max(page.speed, 1)

    def _ramp(self, page: Page) -> float:
        return page.accel * self._unit(page)

    def _begin(self, page: Page, frame: JointFrame | None, first: int = 0) -> None:
        ids = page_joints(page)
        prev = {j: float(self._pos[k]) for k, j in enumerate(self._ids)}
        pvel = {j: float(self._vel[k]) for k, j in enumerate(self._ids)}
        # From the goal each joint holds, not the present position it sags to (frames.py).
        start = np.array(
            [prev.get(j, frame.start_of(j) if frame is not None else 0.0) for j in ids]
        )
        self._page, self._ids = page, ids
        self._pos, self._vel = start, np.array([pvel.get(j, 0.0) for j in ids])
        self._frames = page_targets(page, ids, start)
        self._step, self._repeat, self._entry = first, 0, first
        self.claim(self._playable(ids))
        self._emit_page(page, "started")
        self._start_step()

    def _duration(self, page: Page, k: int, start: np.ndarray) -> float:
        step = page.steps[k]
        if page.schedule == SCHEDULE_SPEED:
            move = float(np.max(np.abs(self._frames[k] - start))) if len(start) else 0.0
            return math.degrees(move) / (max(step.time, 1) * SPEED_BASED_DEG_S)
        return max(step.time, 1) * self._unit(page)

    def _end_velocity(self, k: int, durations: tuple[float, float]) -> np.ndarray:
        """Via-point speeds at the end of step ``k`` (0 where the joint must stop)."""
        page = self._page
        assert page is not None
        last = k == len(page.steps) - 1
        if last or self._braking or page.steps[k].pause > 0 or page.schedule == SCHEDULE_SPEED:
            return np.zeros(len(self._ids))
        # Entering at a later step (play from a step), the joints come from where they are.
        before = self._frames[k - 1] if k > self._entry else self._pos
        d_in = self._frames[k] - before
        d_out = self._frames[k + 1] - self._frames[k]
        same = np.sign(d_in) * np.sign(d_out) > 0
        speed = np.minimum(np.abs(d_in) / durations[0], np.abs(d_out) / durations[1])
        return np.where(same, np.sign(d_in) * speed, 0.0)

    def _start_step(self) -> None:
        page = self._page
        assert page is not None
        k = self._step
        dur = self._duration(page, k, self._pos)
        nxt = self._duration(page, k + 1, self._frames[k]) if k + 1 < len(page.steps) else dur
        v1 = self._end_velocity(k, (dur, nxt))
        self._seg = _Segment.plan(self._pos, self._frames[k], self._vel, v1, dur, self._ramp(page))
        self._phase, self._t = "move", 0.0

    def _advance(self, dt: float) -> None:
        page, seg = self._page, self._seg
        assert page is not None and seg is not None
        self._t += dt
        if self._phase == "move":
            self._pos, self._vel = seg.at(self._t)
            if self._t < seg.duration - 1e-9:
                return
            spill = self._t - seg.duration
            pause = page.steps[self._step].pause * self._unit(page)
            if pause > 0 and not self._braking:
                self._phase, self._t = "pause", spill
                self._vel = np.zeros_like(self._vel)
                return
            self._next_step()
        elif self._t >= page.steps[self._step].pause * self._unit(page):
            self._next_step()

    def _next_step(self) -> None:
        page = self._page
        assert page is not None
        if self._braking:
            self._finish("braked")
            return
        self._step += 1
        if self._step < len(page.steps):
            self._start_step()
            return
        self._repeat += 1
        self._vel = np.zeros_like(self._vel)
        if self._repeat < max(page.repeat, 1) and not self._stopping:
            self._step = self._entry = 0
            self._start_step()
            return
        follow = page.exit if self._stopping else page.next
        self._emit_page(page, "finished")
        if follow and follow in self.library:
            stopping = self._stopping
            self._begin(self.library.page(follow), None)
            self._stopping = stopping and follow != page.exit
            return
        self._finish("finished", emit=False)

    def _emit_page(self, page: Page, state: str) -> None:
        self.emit(
            "action",
            f"page {page.number} ({page.name}) {state}",
            page=page.number,
            name=page.name,
            state=state,
        )

    def _finish(self, how: str, release: bool = True, emit: bool = True) -> None:
        page = self._page
        if page is not None and emit:
            self._emit_page(page, how)
        self._page, self._seg, self._phase = None, None, "idle"
        self._stopping = self._braking = False
        if release:
            # Unowned joints keep their last goal in the manager: the final pose is held.
            self.release()

    def on_released(self, ids: set[int]) -> None:
        # Another module took joints: play on with the rest, or end when none are left.
        if self._page is not None and not self.owned():
            self._finish("interrupted", release=False)

    def status(self) -> dict[str, Any]:
        page = self._page
        return {
            "active": self.active,
            "playing": self.playing,
            "page": page.number if page else None,
            "name": page.name if page else None,
            "step": self._step + 1 if page else None,
            "stopping": self._stopping,
        }
