"""Whether the robot is reachable, shown in Foxglove: while its daemon's ``alive`` liveliness
token is absent (the daemon stopped, its link or its router is away) the server publishes an
error status naming that — again every period, so a Foxglove that connects meanwhile sees it
too — so the panels' last values are not taken for live data; it is removed when the token is
back. The same token the TUI and ``darwin list`` go by.

Asked (a liveliness query each period) rather than subscribed: a liveliness subscriber declared
as the session opens can miss the token that already exists, and then never sees it."""

from __future__ import annotations

import contextlib
import threading
from typing import Any

from foxglove.websocket import StatusLevel

STATUS_ID = "darwin-robot-presence"
PERIOD_S = 1.0


class Presence:
    def __init__(self, robot: Any, server: Any) -> None:
        self.robot = robot
        self.server = server
        self.away: bool | None = None  # unknown until first asked
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="presence", daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                away = not self.robot.alive(PERIOD_S)
            except Exception:  # a session closing under us
                away = True
            self._show(away)
            self._stop.wait(PERIOD_S)

    def _show(self, away: bool) -> None:
        was, self.away = self.away, away
        with contextlib.suppress(Exception):  # the server may be stopping
            if away:
                target = self.robot.target
                self.server.publish_status(
                    f"robot {target.robot} is unreachable at {target.endpoint}: the values "
                    "shown are its last ones; waiting for it to come back",
                    StatusLevel.Error, id=STATUS_ID,
                )
            elif was:
                self.server.remove_status([STATUS_ID])

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=PERIOD_S * 3)
