"""A fleet in the TUI: the live robots at the app's endpoint (for the connect screen's list)
and F3, switching to the next of them. Mixed into :class:`clients.tui.app.DarwinApp`.
"""

from __future__ import annotations

from typing import Any

from clients.fleet import RobotRecord, discover, discover_at
from clients.tui.connect import RobotFinder
from clients.tui.i18n import _
from clients.tui.link import Link
from clients.tui.model import Model
from clients.tui.settings import Settings

FIND_TIMEOUT_S = 1.0  # how long the robot list waits for each robot's status


class FleetMixin:
    """Needs what :class:`DarwinApp` has: the link, the model, the settings, ``find_robots``,
    ``connect`` and Textual's ``App`` (``notify``, ``run_worker``, ``call_from_thread``)."""

    link: Link
    model: Model
    settings: Settings
    find_robots: RobotFinder | None
    connect: Any
    notify: Any
    run_worker: Any
    call_from_thread: Any

    def _find_robots(self, endpoint: str) -> list[RobotRecord]:
        """Live robots at ``endpoint`` (in a worker thread), through the link's session when it
        goes there (a router's: the fleet), else a session of its own."""
        robot = self.link.robot
        if robot is not None and robot.target.endpoint == endpoint:
            return discover(robot.session, timeout=FIND_TIMEOUT_S)
        return discover_at(endpoint, timeout=FIND_TIMEOUT_S, creds=self.link.credentials)

    def action_next_robot(self) -> None:
        """Switch to the next live robot at the same endpoint (by name, wrapping round)."""
        finder, endpoint = self.find_robots, self.settings.endpoint
        if finder is None:
            self.notify(_("No robot list without a connection."), severity="warning")
            return

        def find() -> None:
            try:
                names = [r.name for r in finder(endpoint)]
            except Exception as exc:  # unreachable, or the session closed: say so
                self.call_from_thread(self.notify, str(exc), severity="error", timeout=8)
                return
            self.call_from_thread(self._switch_robot, names)

        self.run_worker(find, thread=True, exclusive=True, group="next-robot")

    def _switch_robot(self, names: list[str]) -> None:
        current = self.settings.robot
        others = [n for n in names if n != current]
        if not others:
            self.notify(
                _("No other live robot at {endpoint}.").format(endpoint=self.settings.endpoint)
            )
            return
        later = [n for n in others if n > current]
        nxt = (later or others)[0]
        self.connect(Settings(self.settings.endpoint, nxt, self.settings.name, self.settings.lang))
        self.model.status = None  # the previous robot's state must not show as this one's
        self.model.bump("status")
        self.notify(_("Switched to {robot}.").format(robot=nxt))
