"""The TUI in a fleet, against real processes: a router and two simulated robots joined to it.
The connect screen lists both live robots to pick from; F3 switches to the next one."""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from textual.widgets import OptionList

from clients.tui.app import DarwinApp
from clients.tui.connect import ConnectScreen
from clients.tui.messages import LinkState
from tests.fixtures.fleet import RunningRouter, start_router
from tests.fixtures.system import start_system
from tests.ui.live import until


@pytest.fixture(scope="module")
def fleet() -> Iterator[tuple[RunningRouter, list[str]]]:
    tag = uuid.uuid4().hex[:6]
    a, b = f"op1-{tag}", f"op2-{tag}"
    with (
        start_router() as router,
        start_system(router=router.endpoint, robot=a, gateway=False),
        start_system(router=router.endpoint, robot=b, gateway=False),
    ):
        yield router, [a, b]


def on_robot(app: DarwinApp, name: str) -> bool:
    """Connected to ``name`` and showing its own status."""
    status = app.model.status
    return (
        app.link_info.state is LinkState.CONNECTED
        and app.link_info.robot == name
        and status is not None
        and status.robot == name
    )


async def test_connect_screen_lists_the_fleet_and_a_key_switches_robots(
    fleet: tuple[RunningRouter, list[str]], settings_file: Path
) -> None:
    router, (a, b) = fleet
    app = DarwinApp(endpoint=router.endpoint, robot=a, name="fleet", settings_path=settings_file)
    async with app.run_test(size=(100, 30)) as pilot:
        await until(pilot, lambda: on_robot(app, a), f"the link to {a}")
        await pilot.press("c")
        await until(pilot, lambda: isinstance(app.screen, ConnectScreen), "the connect screen")
        screen = app.screen
        assert isinstance(screen, ConnectScreen)
        await until(
            pilot, lambda: {a, b} <= {r.name for r in screen.found}, "both robots in the list"
        )
        robots = screen.query_one("#robots", OptionList)
        labels = [str(robots.get_option_at_index(i).prompt) for i in range(robots.option_count)]
        assert any(label.startswith(a) for label in labels), labels
        assert any(label.startswith(b) for label in labels), labels
        # Pick the other robot from the list: the UI connects to it through the same router.
        robots.focus()
        robots.highlighted = [r.name for r in screen.found].index(b)
        await pilot.press("enter")
        await until(pilot, lambda: on_robot(app, b), f"the link to {b}")
        assert app.settings.endpoint == router.endpoint
        # F3: the next live robot (wrapping round), without the connect screen.
        await pilot.press("f3")
        await until(pilot, lambda: on_robot(app, a), f"F3 switching back to {a}")
