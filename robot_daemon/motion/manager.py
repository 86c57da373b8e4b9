"""The motion manager: runs modules in order each tick; every joint has exactly one owner.

Ownership moves only through ``claim`` (explicit hand-over: the previous owner is told) and
``release``. Joints nobody owns keep the goal they last had: ``halt``, a release and the port's
return write that last goal again (with the configured gains, so a module's own gains end with
it), never the present position. A servo with P = 32 and I = 0 stands below its goal under load
by its steady-state error; re-commanding where it stands made a loaded joint sink each time.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from config.loader import RobotConfig
from robot_daemon.frames import N_SLOTS, JointFrame, Targets
from robot_daemon.motion.interface import MotionModule

_NONE: frozenset[int] = frozenset()
# Every servo online with torque on, as a frame's bool arrays' bytes past slot 0.
_ALL_HELD = b"\x01" * (N_SLOTS - 1)


class MotionManager:
    def __init__(self, robot: RobotConfig, modules: list[MotionModule] | None = None) -> None:
        self.robot = robot
        self.modules: list[MotionModule] = []
        self._by_name: dict[str, MotionModule] = {}
        self._owner: dict[int, str | None] = {jid: None for jid in robot.ids}
        # Joints by owner, made from ``_owner`` when first asked after a change: the tick asks
        # for every module's, twice.
        self._owned: dict[str | None, frozenset[int]] | None = None
        # status's "owners", and the ``_owned`` it was made for
        self._owners: dict[str, str | None] = {}
        self._owners_of: dict[str | None, frozenset[int]] | None = None
        self._hold: dict[int, float] = {}  # goals of unowned joints to (re)write, e.g. after halt
        self._last_goal: dict[int, float] = {}
        self.events: deque[tuple[str, str, dict[str, Any]]] = deque(maxlen=1000)
        self.last_frame: JointFrame | None = None
        # The lease holder's client id, set by the daemon when the lease changes (None: nobody
        # holds it). Motion that starts itself asks it (robot_daemon/motion_authority.py).
        self.controller: str | None = None
        for m in modules or []:
            self.add(m)

    # -- modules ---------------------------------------------------------------------------
    def add(self, module: MotionModule) -> MotionModule:
        if module.name in self._by_name:
            raise ValueError(f"a motion module named {module.name!r} is already registered")
        module.attach(self)
        self.modules.append(module)
        self._by_name[module.name] = module
        return module

    def module(self, name: str) -> MotionModule:
        return self._by_name[name]

    def get(self, name: str) -> MotionModule | None:
        return self._by_name.get(name)

    # -- ownership -------------------------------------------------------------------------
    def owner(self, joint_id: int) -> str | None:
        return self._owner.get(joint_id)

    def owned_by(self, name: str) -> frozenset[int]:
        return self._owned_map().get(name, _NONE)

    def _owned_map(self) -> dict[str | None, frozenset[int]]:
        if self._owned is None:
            by: dict[str | None, set[int]] = {}
            for j, o in self._owner.items():
                by.setdefault(o, set()).add(j)
            self._owned = {o: frozenset(js) for o, js in by.items()}
        return self._owned

    def claim(self, name: str, ids: set[int]) -> None:
        if name not in self._by_name:
            raise KeyError(f"no motion module named {name!r}")
        unknown = ids - set(self._owner)
        if unknown:
            raise KeyError(f"unknown joint ids {sorted(unknown)}")
        taken: dict[str, set[int]] = {}
        for j in ids:
            prev = self._owner[j]
            if prev is not None and prev != name:
                taken.setdefault(prev, set()).add(j)
            self._owner[j] = name
            self._owned = None
            self._hold.pop(j, None)
        for prev, lost in taken.items():
            self._by_name[prev].on_released(lost)

    def release(self, name: str, ids: set[int] | None = None) -> None:
        for j, o in self._owner.items():
            if o == name and (ids is None or j in ids):
                self._owner[j] = None
                self._owned = None
                if j in self._last_goal:  # written again with the configured gains
                    self._hold[j] = self._last_goal[j]

    # -- events ----------------------------------------------------------------------------
    def emit(self, kind: str, message: str, **data: Any) -> None:
        self.events.append((kind, message, data))

    def drain_events(self) -> list[tuple[str, str, dict[str, Any]]]:
        out = list(self.events)
        self.events.clear()
        return out

    # -- the tick ----------------------------------------------------------------------------
    def step(self, frame: JointFrame) -> Targets:
        self.last_frame = frame
        online, torque = frame.online, frame.torque_enabled
        # Most ticks every servo holds (slot 0 is unused): its 20 bools' bytes say so without
        # three numpy calls.
        if online.tobytes()[1:] != _ALL_HELD or torque.tobytes()[1:] != _ALL_HELD:
            limp = ~(online & torque)
            if limp[1:].any():
                self.stop_limp(frame, limp)
        targets = Targets()
        for m in self.modules:
            m.observe(frame)
        by_owner = self._owned_map()
        for m in self.modules:
            owned = by_owner.get(m.name, _NONE)
            if not owned:
                continue
            goals = m.step(frame)
            # A module never writes a joint it does not own. (The usual tick, one module
            # driving every joint it owns, is a dict update: no loop over 20 joints.)
            if owned.issuperset(goals):
                targets.goal.update(goals)
            else:
                targets.goal.update((j, g) for j, g in goals.items() if j in owned)
            gains = m.gains()
            # A joint released in this step gets the configured gains (no module's).
            kept = self.owned_by(m.name) if gains else owned
            if kept.issuperset(gains):
                targets.gains.update(gains)
            else:
                targets.gains.update((j, pid) for j, pid in gains.items() if j in kept)
            by_owner = self._owned_map()  # its step may have claimed or released joints
        for j, g in self._hold.items():
            targets.goal.setdefault(j, g)
        self._hold.clear()
        self._last_goal.update(targets.goal)
        return targets

    def halt(self, finish_step: bool = False) -> None:
        """Stop every module and hold the pose on every joint.

        ``finish_step`` (the ``halt`` verb): a walk ends at its next double support, within
        half a gait period, and then holds; everything else freezes now. Without it (a lost
        port, a fault, shutdown) everything freezes now."""
        for m in self.modules:
            if finish_step:
                m.halt_safely()
            else:
                m.halt()
        keep = {m.name for m in self.modules if m.finishing}
        for j, o in self._owner.items():
            if o not in keep:
                self._owner[j] = None
        self._owned = None
        frame = self.last_frame
        if frame is not None:
            self.hold_present(frame)
        if keep:
            self.emit(
                "halt",
                "all motion stopped; the walk ends its step at the next double support "
                "(within half a gait period), then holds",
                finishing=sorted(keep),
            )
        else:
            self.emit("halt", "all motion stopped; holding the present pose", finishing=[])

    def hold_present(self, frame: JointFrame) -> None:
        """Hold the pose on every joint nobody owns (halt, shutdown, the port came back): the
        last goal of a joint whose torque is on, offline or not (its replies may be lost while
        it still hears); a joint without torque has no goal to keep (enabling it holds where
        it is, bus/robot_bus.py). The one move of ``MOVE_HOLD``
        (robot_daemon/motion_authority.py)."""
        self._hold = {
            j: self._last_goal[j]
            for j, o in self._owner.items()
            if o is None and frame.torque_enabled[j] and j in self._last_goal
        }

    def stop_limp(self, frame: JointFrame, limp: np.ndarray) -> None:
        """No motion on a limp joint (``MOVE_LIMP_JOINT_STOP``, robot_daemon/
        motion_authority.py): a module driving a joint that went offline or torque off (its
        alarm shutdown, a ``torque`` command) stops as ``halt`` stops it, and so do the modules
        that sequence it. One event says which servo and what stopped."""
        hit: dict[str, list[int]] = {}
        for j in np.flatnonzero(limp).tolist():
            owner = self._owner.get(j)
            if owner is not None and self._by_name[owner].in_motion:
                hit.setdefault(owner, []).append(j)
        if not hit:
            return
        stopped = list(hit)
        # What drives the stopped module (ball play the walk, a choreography its items, a walk
        # its walk-ready page) stops too, or it would start it again on the limp joint.
        for m in self.modules:
            if m.sequencing and m.name not in hit:
                m.halt()
                stopped.append(m.name)
        for name, ids in hit.items():
            self._by_name[name].on_limp(set(ids))
        ids = sorted(j for js in hit.values() for j in js)
        names = self.robot.by_id
        servos = ", ".join(
            f"servo {j} ({names[j].name}) {'offline' if not frame.online[j] else 'torque off'}"
            for j in ids
        )
        finishing = [n for n in stopped if self._by_name[n].finishing]
        self.emit(
            "motion_stopped",
            f"{', '.join(stopped)} stopped: {servos}"
            + ("; the walk ends at its next double support" if finishing else "; holding"),
            modules=stopped,
            ids=ids,
        )

    def stop_all(self) -> None:
        """Ask every module to stop gracefully (lease loss, fall)."""
        for m in self.modules:
            if m.active:
                m.stop()

    def status(self) -> dict[str, Any]:
        owned = self._owned_map()
        if self._owners_of is not owned:
            # Made again only after ownership changed (``_owned`` is remade then): twenty
            # str(id) cost ~30 k instructions a status message, ten times a second.
            self._owners = {str(j): o for j, o in self._owner.items()}
            self._owners_of = owned
        return {
            "owners": dict(self._owners),
            **{m.name: m.status() for m in self.modules},
        }
