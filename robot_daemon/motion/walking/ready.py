"""Before the gait runs: the gyro centre measured, then the walk-ready page.

ROBOTIS's framework runs no motion module before its gyro calibration (``MotionManager.cpp``,
``m_CalibrationStatus``), and its demo plays the stock "walk ready" page before it starts the
gait (``Linux/project/demo/main.cpp``: ``Action::Start(9)``, then waits while it plays). So a
walk started through :class:`~robot_daemon.motion.walking.gait.WalkingModule` goes
"calibrating" → "page" → "" (the gait takes the legs and blends in from the page's pose). The
page plays on the body only: the head keeps its owner, so tracking goes on. Without an action
player the gait takes the legs at once.

:class:`WalkReady` is that sequence, a small state machine the walking module has. It reaches
the action player alone (through a lookup, since the manager attaches the modules after they
are built); what a finished sequence means (take the legs, or report the walk stopped) is the
walking module's.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from typing import Any, Protocol

from robot_daemon.frames import JointFrame

READY_PAGE = 9
HEAD_IDS = (19, 20)


class PagePlayer(Protocol):
    """What the sequence uses of the action player (motion/action/player.py)."""

    @property
    def playing(self) -> bool: ...

    def play(self, ref: int | str, step: int = 1, joints: set[int] | None = None) -> Any: ...


class WalkReady:
    """``state``: "" (idle, or the gait runs), "calibrating" (waiting for the gyro centre),
    "page" (the walk-ready page plays). ``player()`` is the action player, None without one;
    ``ids()`` the robot's joint ids."""

    def __init__(
        self, player: Callable[[], PagePlayer | None], ids: Callable[[], Collection[int]]
    ) -> None:
        self._player = player
        self._ids = ids
        self.state = ""

    def begin(self) -> bool:
        """Start the sequence; False when there is no player (the gait takes the legs now)."""
        self.state = "calibrating" if self._player() is not None else ""
        return bool(self.state)

    def cancel(self) -> None:
        self.state = ""

    def _play_page(self) -> bool:
        player = self._player()
        assert player is not None
        try:
            player.play(READY_PAGE, joints={j for j in self._ids() if j not in HEAD_IDS})
        except (KeyError, ValueError):
            return False  # no such page in this library: blend from the present pose
        return True

    def observe(self, frame: JointFrame, wanted: bool) -> bool:
        """One tick of the sequence; ``wanted``: the walk is still asked for. True on the tick
        it ends (then the walking module takes the legs, or stops when no longer wanted)."""
        if not self.state:
            return False
        if self.state == "calibrating":
            if frame.imu_calibrated and wanted:
                self.state = "page" if self._play_page() else "done"
            elif not wanted:
                self.state = "done"
            if self.state != "done":
                return False  # still calibrating, or the page starts
        elif getattr(self._player(), "playing", False):
            return False
        self.state = ""  # the page ended: the gait blends on from its pose
        return True
