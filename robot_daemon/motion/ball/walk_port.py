"""The walking module as ball play drives it, in the framework's units (mm and degrees per
step), kept in one place so the follower's logic does not depend on the engine's API."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from robot_daemon.motion.manager import MotionManager


class WalkPort:
    def __init__(self, module: Any) -> None:
        self.module = module

    @classmethod
    def of(cls, manager: MotionManager | None) -> WalkPort:
        return cls(manager.get("walking") if manager is not None else None)

    def walk(self, step_mm: float, turn_deg: float) -> None:
        """Walk (starting if stopped) with these step amplitudes."""
        m = self.module
        if m is None:
            return
        m.set_amplitudes(x=step_mm, y=0.0, turn=turn_deg)
        if not self.running():
            m.start()

    def stop(self) -> None:
        m = self.module
        if m is not None and self.running():
            m.stop()

    def running(self) -> bool:
        m = self.module
        return bool(m is not None and getattr(m, "running", False))
