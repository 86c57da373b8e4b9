"""SVG snapshots of the Actions tab on the fixed scene: the library, a page open, teach mode
(reviewed by eye; ``pytest tests/ui --snapshot-update`` rewrites them after an intended change).
The library is the shipped one, as the ``pages`` verb would list it."""

from __future__ import annotations

from collections.abc import Awaitable, Callable

import pytest
from textual.pilot import Pilot

from clients.pages import joints_of
from clients.tui.tabs.actions import ActionsTab
from robot_daemon.arbiter.verbs.pages import page_summary
from robot_daemon.motion.action import textfile
from robot_daemon.motion.action.library import load_library
from tests.ui.test_snapshots import settle


def listing() -> list[dict]:
    lib = load_library()
    return [page_summary(n, p, "shipped") for n, p in sorted(lib.pages.items())]


def scene(open_page: int | None = None, teach: bool = False) -> Callable[[Pilot], Awaitable[None]]:
    async def run_before(pilot: Pilot) -> None:
        await settle(pilot)
        tab = pilot.app.current_tab()
        assert isinstance(tab, ActionsTab)
        tab.st.listing = listing()
        tab.show_listing()
        if open_page is not None:
            tab.open(textfile.page_to_dict(load_library().page(open_page)))
            await pilot.press("down", "right", "right")
        if teach:
            tab.st.limp = joints_of("right_arm")
            tab.show_page()
            tab.show_status()
        await pilot.pause(0.1)

    return run_before


@pytest.mark.parametrize(
    ("name", "page", "teach"), [("browse", None, False), ("page", 4, False), ("teach", 4, True)]
)
def test_actions_tab(snap_compare, scene_app, name: str, page: int | None, teach: bool) -> None:
    app = scene_app(tab="actions")
    assert snap_compare(app, terminal_size=(120, 36), run_before=scene(page, teach))
