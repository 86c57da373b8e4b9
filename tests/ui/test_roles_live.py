"""The TUI against a robot with access control (`darwin up --auth`): what the connection's role
may not do is greyed out in the footer and does nothing; an operator's keys stay live."""

from __future__ import annotations

from collections.abc import AsyncIterator, Iterator
from contextlib import asynccontextmanager
from pathlib import Path

import pytest
from rich.text import Text
from textual.pilot import Pilot

from clients.tui.app import DarwinApp
from schemas.roles import Role
from schemas.session import Credentials
from tests.fixtures.system import RunningSystem, start_system
from tests.integration.test_auth import PASSWORDS, make_users
from tests.ui.live import connected, show_tab, until


@pytest.fixture(scope="module")
def auth_system(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningSystem]:
    users = make_users(tmp_path_factory.mktemp("tui-auth"))
    with start_system(extra_args=["--auth", str(users)], gateway=False) as system:
        yield system


@asynccontextmanager
async def signed_in(
    system: RunningSystem, settings: Path, user: str, role: Role
) -> AsyncIterator[tuple[DarwinApp, Pilot[None]]]:
    """The TUI connected to ``system`` as ``user``, whose role the daemon reports as ``role``."""
    app = DarwinApp(
        endpoint=system.endpoint, robot=system.robot, name=f"tui-{user}", lang="en",
        settings_path=settings, credentials=Credentials(user, PASSWORDS[user]),
    )
    async with app.run_test(size=(140, 40)) as pilot:
        await connected(pilot)
        assert app.link.role == role
        yield app, pilot


def enabled(app: DarwinApp, action: str) -> bool:
    found = [a.enabled for a in app.screen.active_bindings.values() if a.binding.action == action]
    assert found, f"no binding for {action}"
    return all(found)


def greyed(app: DarwinApp) -> set[str]:
    """Descriptions the footer shows struck through (greyed)."""
    bar: Text = app.screen.query_one("KeyBar").render()  # type: ignore[assignment]
    struck = [span for span in bar.spans if "strike" in str(span.style)]
    return {bar.plain[span.start : span.end].strip() for span in struck}


async def test_an_observer_sees_commands_greyed_and_they_do_nothing(
    auth_system: RunningSystem, settings_file: Path
) -> None:
    async with signed_in(auth_system, settings_file, "obs", Role.OBSERVER) as (app, pilot):
        assert not enabled(app, "lease") and not enabled(app, "halt")
        assert {"HALT", "Lease take/release"} <= greyed(app)
        before = app.model.event_count
        await pilot.press("l")  # a greyed key does not run: nothing sent, nothing refused
        await pilot.pause(0.3)
        assert app.model.status is not None and app.model.status.lease is None
        # The robot's own events (its gyro centre measured, …) may arrive meanwhile; none may be
        # about the lease this key would have taken.
        arrived = app.model.events_since(before)
        assert not [e for e in arrived if e.kind == "lease"], arrived
        await show_tab(pilot, 5)  # Walk
        assert not enabled(app, "move(1, 0, 0)")
        assert "Forward" in greyed(app)
        # Reading the gait is not a command: the observer's Walk tab shows the parameters.
        await until(pilot, lambda: app.model.edits.walk_params, "the gait parameters read")
        await until(pilot, lambda: app.screen.query("#param-period_time"), "the gait form")
        assert app.screen.query_one("#params-apply").disabled  # setting it needs an operator


async def test_an_operator_keeps_every_key(
    auth_system: RunningSystem, settings_file: Path
) -> None:
    async with signed_in(auth_system, settings_file, "op", Role.OPERATOR) as (app, pilot):
        assert enabled(app, "lease") and enabled(app, "halt")
        assert greyed(app) == set()
        await show_tab(pilot, 5)  # Walk: the operator may set the gait
        await until(pilot, lambda: app.screen.query("#param-period_time"), "the gait form")
        assert not app.screen.query_one("#params-apply").disabled
