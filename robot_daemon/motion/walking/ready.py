"""Before the gait runs: the gyro centre measured, then the walk-ready page.

ROBOTIS's framework runs no motion module before its gyro calibration (``MotionManager.cpp``,
``m_CalibrationStatus``), and its demo plays the stock "walk ready" page before it starts the
gait (``Linux/project/demo/main.cpp``: ``Action::Start(9)``, then waits while it plays). So a
walk started through :class:`~robot_daemon.motion.walking.gait.WalkingModule` goes
"calibrating" → "page" → "" (the gait takes the legs and blends in from the page's pose). The
page plays on the body only: the head keeps its owner, so tracking goes on. Without an action
player the gait takes the legs at once.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robot_daemon.frames import JointFrame
from robot_daemon.motion.interface import MotionModule

if TYPE_CHECKING:
    from robot_daemon.motion.manager import MotionManager

READY_PAGE = 9
HEAD_IDS = (19, 20)


class WalkReady(MotionModule):
    """Mixed into the walking module (which holds ``running``, ``ctrl_running``, ``steps``)."""

    manager: MotionManager | None
    running: bool
    ctrl_running: bool
    steps: int
    _readying: str
    claim_ids: tuple[int, ...] = ()

    def _action(self) -> MotionModule | None:
        return self.manager.get("action") if self.manager is not None else None

    def _play_ready_page(self) -> bool:
        action = self._action()
        assert action is not None and self.manager is not None
        body = {j for j in self.manager.robot.ids if j not in HEAD_IDS}
        try:
            # The manager hands back a MotionModule; the one named "action" is the player.
            action.play(READY_PAGE, joints=body)  # type: ignore[attr-defined]
        except (KeyError, ValueError):
            return False  # no such page in this library: blend from the present pose
        return True

    def observe(self, frame: JointFrame) -> None:
        if not self._readying:
            return
        if self._readying == "calibrating":
            if frame.imu_calibrated and self.ctrl_running:
                self._readying = "page" if self._play_ready_page() else "done"
            elif not self.ctrl_running:
                self._readying = "done"
            if self._readying != "done":
                return  # still calibrating, or the page starts
        elif getattr(self._action(), "playing", False):
            return
        self._readying = ""  # the page ended: the gait blends on from its pose
        if self.ctrl_running and self.running:
            self.claim(self.claim_ids)
        elif self.running:
            self.running = False
            self.emit("walk", "walking stopped", state="stopped", steps=self.steps)

    @property
    def active(self) -> bool:
        # Waiting for the gyro or the walk-ready page it owns nothing yet, but it is running:
        # a lease that ends (stop_all) or a fall must stop it before it takes the legs.
        return self.running or bool(self.owned())
