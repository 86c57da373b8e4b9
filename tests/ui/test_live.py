"""The TUI against a real daemon on the emulator (``darwin up``): connect, joints, lease,
walk, pose, choreography, language, halt without the lease, two TUIs at once."""

from __future__ import annotations

import math

from textual.widgets import DataTable

from clients.tui.tabs.behaviours import choreography_state
from tests.ui.live import connected, holder, live_app, show_tab, toggle_lease, until


async def test_connects_remembers_and_shows_live_joints(robot_system, settings_file) -> None:
    app = live_app(robot_system, settings_file, "tui-watch")
    async with app.run_test(size=(120, 40)) as pilot:
        await connected(pilot)
        assert settings_file.exists() and robot_system.endpoint in settings_file.read_text()
        await show_tab(pilot, 2)
        table = app.screen.query_one("#joint-table", DataTable)
        first = app.model.joints.tick
        await until(pilot, lambda: app.model.joints.tick > first + 10, "newer joints")
        await until(pilot, lambda: table.get_cell("1", "pos").strip() != "", "a filled table")
        shown = float(table.get_cell("1", "pos"))
        assert abs(shown - math.degrees(app.model.joints.position[0])) < 5.0
        assert "loop" in str(app.screen.query_one("RobotHeader").render())


async def test_lease_pose_and_a_second_tui_watching(robot_system, settings_file, tmp_path) -> None:
    driver = live_app(robot_system, settings_file, "tui-driver")
    watcher = live_app(robot_system, tmp_path / "other.toml", "tui-watcher")
    async with driver.run_test(size=(120, 40)) as pd, watcher.run_test(size=(120, 40)) as pw:
        await connected(pd)
        await connected(pw)
        await toggle_lease(pd, take=True)
        await until(pw, lambda: holder(watcher) == driver.link.client_id, "the lease seen")
        await until(
            pw,
            lambda: "held by tui-driver" in str(pw.app.screen.query_one("RobotHeader").render()),
            "the watcher's header naming the holder",
        )
        # The watcher cannot move the robot: its command is refused and logged.
        await show_tab(pw, 2)
        before = watcher.model.event_count
        await pw.press("right_square_bracket")
        # The robot's own events (the loop's timing, …) may arrive meanwhile: look for the refusal.
        await until(
            pw,
            lambda: any("busy" in e.message for e in watcher.model.events_since(before)),
            "the refusal",
        )

        # The driver edits a pose (+10° on joint 1) and applies it as a timed pose.
        await show_tab(pd, 3)
        await pd.press("m")
        start = driver.model.edits.pose[1]
        await pd.press("right_square_bracket", "right_square_bracket", "s", "p")
        target = start + math.radians(10)
        await until(
            pd,
            lambda: abs(driver.model.joints.goal[0] - target) < math.radians(1.5),
            "joint 1's goal at the applied pose",
        )
        # The watcher halts without the lease: always accepted.
        before = watcher.model.event_count
        await pw.press("ctrl+x")
        await until(
            pw,
            lambda: any(e.kind == "halt" for e in watcher.model.events_since(before)),
            "the halt acknowledged",
        )
        await toggle_lease(pd, take=False)


async def test_walk_with_keys_and_stop(robot_system, settings_file) -> None:
    app = live_app(robot_system, settings_file, "tui-walker")
    async with app.run_test(size=(120, 40)) as pilot:
        await connected(pilot)
        await toggle_lease(pilot, take=True)
        await show_tab(pilot, 5)
        await pilot.press("w")

        def walking() -> bool:
            state = app.model.status.motion.get("walking", {})
            return bool(state.get("walking"))

        await until(pilot, walking, "status saying the robot walks")
        assert "x +0.02" in str(app.screen.query_one("#walk-state").render())
        await pilot.press("space")
        await until(pilot, lambda: not walking(), "status saying the robot stopped")
        await toggle_lease(pilot, take=False)


async def test_build_and_play_a_choreography_in_portuguese(robot_system, settings_file) -> None:
    app = live_app(robot_system, settings_file, "tui-dancer", lang="pt")
    async with app.run_test(size=(120, 40)) as pilot:
        await connected(pilot)
        await until(pilot, lambda: app.model.edits.behaviours, "the behaviour library")
        await toggle_lease(pilot, take=True)
        await show_tab(pilot, 6)
        kinds = [e.get("kind") for e in app.model.edits.behaviours]
        library = app.screen.query_one("#library")
        for kind in ("pause", "walk"):
            library.highlighted = kinds.index(kind)
            await pilot.press("enter")
        assert [i.get("duration") for i in app.model.edits.choreography] == [1.0, 3.0]
        await pilot.press("p")

        def playing() -> bool:
            return bool(choreography_state(app.model.status).get("playing"))

        await until(pilot, playing, "the choreography playing")
        assert "a tocar" in str(app.screen.query_one("#choreography").border_subtitle)
        await pilot.press("o")
        await until(pilot, lambda: not playing(), "the choreography stopped")
        await toggle_lease(pilot, take=False)
