"""Helpers of the UI tests that run against a real daemon (``robot_system``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from textual.pilot import Pilot

from clients.tui.app import TABS, DarwinApp
from clients.tui.messages import LinkState
from tests.fixtures.system import RunningSystem

DEADLINE_S = 20.0


def live_app(system: RunningSystem, settings: Path, name: str, lang: str = "en") -> DarwinApp:
    return DarwinApp(
        endpoint=system.endpoint, robot=system.robot, name=name, lang=lang, settings_path=settings
    )


async def until(pilot: Pilot, condition: Callable[[], object], what: str) -> None:
    """Let the app run until ``condition()`` holds (a generous deadline, not a timing)."""
    deadline = time.monotonic() + DEADLINE_S
    while not condition():
        if time.monotonic() > deadline:
            app = pilot.app
            status = getattr(getattr(app, "model", None), "status", None)
            lease = getattr(status, "lease", None)
            log = getattr(getattr(app, "model", None), "events", None)
            last = [getattr(e, "message", e) for e in list(log or [])[-5:]]
            raise AssertionError(
                f"timed out waiting for {what} (lease holder: {lease}; last events: {last})"
            )
        await pilot.pause(0.05)


async def connected(pilot: Pilot) -> None:
    app = pilot.app
    assert isinstance(app, DarwinApp)
    await until(
        pilot,
        lambda: (
            app.link_info.state is LinkState.CONNECTED
            and app.model.joints is not None
            and app.model.status is not None
        ),
        "the link to the daemon and the first joints and status",
    )


async def show_tab(pilot: Pilot, number: int) -> None:
    """Switch tabs with the number key and wait until the tab holds the focus: a tab's keys
    are bound to the tab, so a key sent before the focus moves in would go nowhere."""
    app = pilot.app
    assert isinstance(app, DarwinApp)
    tab_id = TABS[number - 1][0]
    await pilot.press(str(number))

    def focused_inside() -> bool:
        tab, focused = app.current_tab(), app.focused
        return (
            tab is not None
            and tab_id == tab.TAB_ID
            and focused is not None
            and tab in focused.ancestors_with_self
        )

    await until(pilot, focused_inside, f"tab {number} ({tab_id}) to take the focus")


def holder(app: DarwinApp) -> str | None:
    lease = app.model.status.lease if app.model.status else None
    return lease.get("client") if lease else None


async def toggle_lease(pilot: Pilot, take: bool) -> None:
    """Press the lease key and wait until this UI holds the lease (``take``) or nobody does."""
    app = pilot.app
    assert isinstance(app, DarwinApp)
    await pilot.press("l")
    if take:
        await until(pilot, lambda: holder(app) == app.link.client_id, "the lease")
    else:
        await until(pilot, lambda: holder(app) is None, "the lease released")
