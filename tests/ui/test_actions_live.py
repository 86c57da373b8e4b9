"""The Actions tab against a real daemon on the emulator: a new page, the right arm limp and moved
by hand (a key that pushes it through the emulator's control API, and the API itself), capture,
mirror and undo, save, back to the list, a stock pose, then the page played until the
emulator's goals are the captured angles. Pages go to a temporary user library."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import pytest
from textual.widgets import DataTable

from clients.pages import joints_of
from clients.tui.tabs.actions import ActionsTab, ConfirmScreen
from schemas.sim_control import SimControl
from tests.fixtures.system import RunningSystem, start_system
from tests.ui.live import connected, live_app, show_tab, toggle_lease, until

RIGHT_ARM = {1: "r_shoulder_pitch", 3: "r_shoulder_roll", 5: "r_elbow"}
BY_HAND = {3: 0.35, 5: 0.7}  # rad, set through the control API (shoulder pitch: by key)


@pytest.fixture(scope="module")
def teach_ui_system(
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[tuple[RunningSystem, Path]]:
    user = tmp_path_factory.mktemp("motions")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("DARWIN_MOTIONS", str(user))
        with start_system(gateway=False) as system:
            yield system, user


async def open_row(pilot, tab: ActionsTab, number: int) -> None:
    await until(pilot, lambda: any(r["number"] == number for r in tab.st.listing), f"page {number}")
    table = tab.query_one("#pages-list", DataTable)
    table.focus()
    table.move_cursor(row=[r["number"] for r in tab.st.listing].index(number))
    await pilot.press("enter")
    await until(
        pilot,
        lambda: tab.editor is not None and tab.editor.page["number"] == number,
        f"page {number} open",
    )


async def test_teach_a_page_in_the_tui_and_play_it(teach_ui_system, settings_file) -> None:
    system, user = teach_ui_system
    app = live_app(system, settings_file, "tui-teacher")
    async with app.run_test(size=(160, 48)) as pilot:
        await connected(pilot)
        await toggle_lease(pilot, take=True)
        await show_tab(pilot, 8)
        tab = app.current_tab()
        assert isinstance(tab, ActionsTab)
        await until(pilot, lambda: len(tab.st.listing) >= 19, "the library listed")

        # A new page, its first step the present pose; the cursor on r_shoulder_pitch.
        await pilot.press("n")
        assert tab.editor is not None and len(tab.editor.steps) == 1
        number = tab.editor.page["number"]
        assert tab.cursor_joint() == "r_shoulder_pitch"
        # Everything limp would drop the standing robot: asked first; "no" changes nothing.
        await pilot.press("A")
        await until(pilot, lambda: isinstance(app.screen, ConfirmScreen), "the confirmation")
        await pilot.press("n")
        await until(pilot, lambda: not isinstance(app.screen, ConfirmScreen), "the answer")
        assert tab.st.limp == [] and all(app.model.joints.torque_enabled)
        await pilot.press("a")  # limp the limb under the cursor: the right arm
        assert tab.st.limp == joints_of("right_arm")
        await until(
            pilot,
            lambda: not any(app.model.joints.torque_enabled[j - 1] for j in RIGHT_ARM),
            "the right arm limp",
        )
        # Pushed by hand: one key press moves shoulder pitch +3° in the emulator…
        before = app.model.joints.position[0]
        await pilot.press("full_stop", "full_stop")
        await until(
            pilot,
            lambda: app.model.joints.position[0] > before + math.radians(2.5),
            "the shoulder pushed by hand",
        )
        # …and the control API moves the others, as a hand would.
        sim = SimControl(app.link.robot.session, system.robot)
        for jid, rad in BY_HAND.items():
            sim.call("set_position", id=jid, rad=rad)
        await until(
            pilot,
            lambda: all(
                abs(app.model.joints.position[j - 1] - r) < 0.005 for j, r in BY_HAND.items()
            ),
            "the arm where the hand put it",
        )
        present = dict(zip(app.model.joints.name, app.model.joints.position, strict=False))
        await pilot.press("k")  # capture: the limp joints into the step; torque back on
        assert tab.st.limp == []
        step = tab.editor.step(0)
        for name in RIGHT_ARM.values():
            assert step[name] == pytest.approx(math.degrees(present[name]), abs=0.1)
        await until(
            pilot,
            lambda: all(app.model.joints.torque_enabled[j - 1] for j in RIGHT_ARM),
            "torque back on",
        )
        left_before = step["l_elbow"]
        await pilot.press("m")  # mirror right → left
        for name in RIGHT_ARM.values():
            assert tab.editor.step(0)["l" + name[1:]] == -tab.editor.step(0)[name]
        await pilot.press("u")  # undo
        assert tab.editor.step(0)["l_elbow"] == left_before
        await pilot.press("m")
        captured = dict(tab.editor.step(0))

        await pilot.press("ctrl+s")
        await until(pilot, lambda: not tab.editor.dirty, "the page saved")
        assert [p.name for p in user.glob("*.toml")] == [f"{number:03d}_new_{number}.toml"]
        await pilot.press("escape")
        await until(pilot, lambda: tab.editor is None, "back to the list")

        # Somewhere else first (page 1's pose), then play the taught page.
        await open_row(pilot, tab, 1)
        await pilot.press("g")
        stand = tab.editor.step(0)
        await until(
            pilot,
            lambda: abs(math.degrees(app.model.joints.goal[4]) - stand["r_elbow"]) < 1.0,
            "the stand pose",
        )
        await pilot.press("escape")
        await open_row(pilot, tab, number)
        assert tab.editor.step(0) == captured
        await pilot.press("p")

        def at_captured() -> bool:
            goals = {int(k): v["goal"] for k, v in sim.call("state")["servos"].items()}
            return all(
                abs(goals[j] - math.radians(captured[n])) < 0.003
                for j, n in enumerate(app.model.joints.name, 1)
                if n in captured
            )

        await until(pilot, at_captured, "the emulator's goals at the captured angles")

        # Done playing, the page is deleted from the list (after a confirmation).
        def playing() -> bool:
            status = app.model.status
            return bool(status and (status.motion.get("action") or {}).get("playing"))

        await until(pilot, lambda: not playing(), "the page played to its end")
        await pilot.press("escape")
        await until(pilot, lambda: tab.editor is None, "back to the list")
        await until(pilot, lambda: any(r["number"] == number for r in tab.st.listing), "listed")
        table = tab.query_one("#pages-list", DataTable)
        table.move_cursor(row=[r["number"] for r in tab.st.listing].index(number))
        await pilot.press("x")
        await until(pilot, lambda: isinstance(app.screen, ConfirmScreen), "the confirmation")
        await pilot.press("y")
        await until(
            pilot, lambda: all(r["number"] != number for r in tab.st.listing), "the page gone"
        )
        assert not list(user.glob("*.toml"))
