"""SVG snapshots of every tab on the fixed scene, at 80×24 and 160×48 (reviewed by eye;
``pytest tests/ui --snapshot-update`` rewrites them after an intended change)."""

from __future__ import annotations

import pytest
from textual.pilot import Pilot
from textual.widgets import Input

from clients.fleet import RobotRecord
from clients.tui.app import TABS

SIZES = {"80x24": (80, 24), "160x48": (160, 48)}


async def settle(pilot: Pilot) -> None:
    await pilot.pause(0.3)
    pilot.app.redraw(force=True)
    await pilot.pause(0.1)


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("tab", [t for t, _title in TABS])
def test_tab(snap_compare, scene_app, tab: str, size: str) -> None:
    assert snap_compare(scene_app(tab=tab), terminal_size=SIZES[size], run_before=settle)


@pytest.mark.parametrize("tab", ["motors", "behaviours"])
def test_tab_in_portuguese(snap_compare, scene_app, tab: str) -> None:
    assert snap_compare(scene_app(lang="pt", tab=tab), terminal_size=(80, 24), run_before=settle)


def test_help_screen(snap_compare, scene_app) -> None:
    assert snap_compare(
        scene_app(tab="walk"), press=["f1"], terminal_size=(80, 24), run_before=settle
    )


def test_connect_screen(snap_compare, scene_app) -> None:
    app = scene_app(tab="imu")
    # A fleet at the endpoint: the list the connect screen shows to pick from.
    app.find_robots = lambda endpoint: [
        RobotRecord("op1", endpoint, "running", "ana", 12.1, [], 125.0),
        RobotRecord("op2", endpoint, "degraded", None, 11.4, [{"id": 7, "bits": 32}], 124.9),
    ]

    async def open_screen(pilot: Pilot) -> None:
        await pilot.press("c")
        await settle(pilot)
        # The focused input's cursor blinks on a timer: drawn steadily, the picture does not
        # depend on when a loaded machine takes it.
        for field in pilot.app.screen.query(Input):
            field.cursor_blink = False
        await settle(pilot)

    assert snap_compare(app, terminal_size=(80, 24), run_before=open_screen)


def test_pose_manipulate(snap_compare, scene_app) -> None:
    async def edit(pilot: Pilot) -> None:
        await settle(pilot)
        await pilot.press("m", "right_square_bracket", "right_square_bracket", "s")
        await pilot.pause(0.1)

    assert snap_compare(scene_app(tab="pose"), terminal_size=(160, 48), run_before=edit)
