"""What a motion module is: the base class the motion manager drives each tick.

The frame it sees and the targets it returns are in ``robot_daemon/frames.py``.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from robot_daemon.frames import JointFrame

if TYPE_CHECKING:
    from robot_daemon.motion.manager import MotionManager


class MotionModule:
    """Base of every motion module. Subclasses override ``step`` and the lifecycle hooks.

    A module only ever gets to write the joints the manager says it owns; it takes joints with
    ``self.claim(ids)`` and gives them back with ``self.release(ids)``.
    """

    name: str = "module"

    def __init__(self) -> None:
        self.manager: MotionManager | None = None

    # -- called by the manager -----------------------------------------------------------
    def attach(self, manager: MotionManager) -> None:
        self.manager = manager

    def step(self, frame: JointFrame) -> dict[int, float]:
        """Goals (rad) for some of the joints this module owns. Called every tick."""
        return {}

    def observe(self, frame: JointFrame) -> None:
        """Called every tick for every module, owning joints or not, before any ``step``:
        for modules that watch (fall detection) or sequence others (choreography)."""

    def gains(self) -> dict[int, tuple[int, int, int]]:
        """Gains for owned joints that differ from the config defaults."""
        return {}

    def on_released(self, ids: set[int]) -> None:
        """Another module took these joints (or they were released): forget them."""

    def stop(self) -> None:
        """Stop gracefully (finish the step, brake to a stable pose)."""

    def halt(self) -> None:
        """Stop now; the manager will hold the present pose."""

    def halt_safely(self) -> None:
        """The ``halt`` verb: stop as soon as the body is safe. Most modules freeze at once
        (``halt``); the walk ends at its next double support (motion/walking/gait.py)."""
        self.halt()

    def on_limp(self, ids: set[int]) -> None:
        """Joints this module drives went limp (offline, torque off, alarm): stop as the
        ``halt`` verb would (a walk at its next double support) and give the joints back,
        unless still finishing. ``MotionManager.stop_limp`` calls it."""
        self.halt_safely()
        if not self.finishing:
            self.release()

    @property
    def sequencing(self) -> bool:
        """Drives other modules now (ball play, a choreography, a walk's walk-ready page)."""
        return False

    @property
    def in_motion(self) -> bool:
        """Runs a motion now: not a halted walk's last step, not a stopped walk's hand-back."""
        return self.active and not self.finishing

    @property
    def finishing(self) -> bool:
        """Still driving its joints after ``halt_safely`` (the walk's last half step)."""
        return False

    @property
    def active(self) -> bool:
        return bool(self.owned())

    def status(self) -> dict[str, Any]:
        return {"active": self.active}

    # -- helpers for subclasses ------------------------------------------------------------
    def owned(self) -> frozenset[int]:
        return self.manager.owned_by(self.name) if self.manager else frozenset()

    def claim(self, ids: set[int] | list[int] | tuple[int, ...]) -> None:
        assert self.manager is not None, f"{self.name} is not attached to a manager"
        self.manager.claim(self.name, set(ids))

    def release(self, ids: Iterable[int] | None = None) -> None:
        if self.manager is not None:
            self.manager.release(self.name, set(ids) if ids is not None else None)

    def emit(self, kind: str, message: str, **data: Any) -> None:
        if self.manager is not None:
            self.manager.emit(kind, message, **data)
