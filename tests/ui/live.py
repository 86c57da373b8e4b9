"""Helpers of the UI tests that run against a real daemon (``robot_system``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from textual.pilot import Pilot

from clients.tui.app import DarwinApp, create_app
from clients.tui.messages import LinkState
from tests.fixtures.system import RunningSystem

DEADLINE_S = 20.0


def live_app(system: RunningSystem, settings: Path, name: str, lang: str = "en") -> DarwinApp:
    return create_app(
        endpoint=system.endpoint, robot=system.robot, name=name, lang=lang, settings_path=settings
    )


async def until(pilot: Pilot, condition: Callable[[], object], what: str) -> None:
    """Let the app run until ``condition()`` holds (a generous deadline, not a timing)."""
    deadline = time.monotonic() + DEADLINE_S
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
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


def holder(app: DarwinApp) -> str | None:
    lease = app.model.status.lease if app.model.status else None
    return lease.get("client") if lease else None
