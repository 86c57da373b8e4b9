"""The Actions tab's editing keys on the fixed scene (no robot): typed values and fields, steps
inserted, moved and deleted, undo, Esc closing the input box before leaving the page."""

from __future__ import annotations

from textual.widgets import Input

from clients.tui.tabs.actions import ActionsTab
from robot_daemon.motion.action import textfile
from robot_daemon.motion.action.library import load_library
from tests.ui.test_snapshots import settle


async def test_edit_a_page_with_keys(scene_app) -> None:
    app = scene_app(tab="actions")
    async with app.run_test(size=(120, 36)) as pilot:
        await settle(pilot)
        tab = app.current_tab()
        assert isinstance(tab, ActionsTab)
        tab.open(textfile.page_to_dict(load_library().page(4)))
        await pilot.pause(0.1)
        editor = tab.editor
        assert editor is not None and len(editor.steps) == 6
        assert tab.cursor_joint() == "r_shoulder_pitch"

        await pilot.press("e", *"12.5", "enter")
        assert editor.step(0)["r_shoulder_pitch"] == 12.48  # the nearest raw step
        await pilot.press("right_square_bracket")
        assert editor.step(0)["r_shoulder_pitch"] == 13.45
        await pilot.press("e", "minus", "enter")  # "-": the step no longer drives it
        assert "r_shoulder_pitch" not in editor.step(0)
        await pilot.press("f", *"name=wave 2", "enter")
        assert editor.page["name"] == "wave 2"
        await pilot.press("f", *"next=oops", "enter")  # not a number: refused, nothing changed
        assert editor.page["next"] == 0

        await pilot.press("i")  # a new step after the first, with its pose
        assert len(editor.steps) == 7 and tab.st.row == 1
        await pilot.press("K")  # moved up: now first
        assert tab.st.row == 0 and editor.steps[0]["time"] == 100
        await pilot.press("x")
        assert len(editor.steps) == 6
        for _ in range(7):  # value, +1, not driven, name, insert, move, delete
            await pilot.press("u")
        assert editor.page == textfile.page_to_dict(load_library().page(4))

        await pilot.press("e")
        assert tab.query_one("#actions-input", Input).display
        await pilot.press("escape")  # closes the box, the page stays open
        assert not tab.query_one("#actions-input", Input).display and tab.editor is not None
        await pilot.press("escape")  # unsaved (the undos count as changes): warned once
        assert tab.editor is not None
        await pilot.press("escape")
        assert tab.editor is None
