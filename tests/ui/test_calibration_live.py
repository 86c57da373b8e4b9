"""The TUI's joint-offset screen (Pose tab, ``o``) against a real daemon on the emulator: the
reference posture, nudge, mirror, undo and save, each seen in the daemon's own offsets."""

from __future__ import annotations

import tomllib
from pathlib import Path

from clients.tui.calibration import STEP_DEG, CalibrationScreen
from tests.fixtures.system import start_system
from tests.ui.live import connected, live_app, show_tab, toggle_lease, until


async def test_nudge_mirror_undo_and_save(settings_file: Path, tmp_path: Path) -> None:
    with start_system(gateway=False) as system, system.robot_client("check") as check:
        app = live_app(system, settings_file, "tui-calibration")
        async with app.run_test(size=(120, 40)) as pilot:
            await connected(pilot)
            await toggle_lease(pilot, take=True)
            await show_tab(pilot, 3)
            await pilot.press("o")
            await until(pilot, lambda: isinstance(app.screen, CalibrationScreen), "the screen")
            screen = app.screen
            assert isinstance(screen, CalibrationScreen)
            view = screen.view
            view.save_path = str(tmp_path / "config.toml")

            def daemon(name: str) -> float:
                return check.calibration.refresh()[name]

            await pilot.press("p")  # the reference posture
            await until(pilot, lambda: max(map(abs, app.model.joints.goal)) < 1e-3, "posture")
            # The cursor starts on the first joint, r_shoulder_pitch: five steps up.
            await pilot.press("plus", "plus", "plus", "plus", "plus")
            wanted = 5 * STEP_DEG
            await until(pilot, lambda: abs(daemon("r_shoulder_pitch") - wanted) < 1e-6, "nudge")
            await pilot.press("m")  # l_shoulder_pitch gets the opposite
            await until(pilot, lambda: abs(daemon("l_shoulder_pitch") + wanted) < 1e-6, "mirror")
            await until(
                pilot, lambda: "+0.439" in str(view.query_one("DataTable").get_row_at(0)), "table"
            )
            await pilot.press("w")
            saved = tomllib.loads((tmp_path / "config.toml").read_text())["robot"]["joints"]
            assert abs(saved["l_shoulder_pitch"]["offset_deg"] + wanted) < 1e-6
            await pilot.press("u")  # the mirror undone
            await until(pilot, lambda: daemon("l_shoulder_pitch") == 0.0, "undo")
            assert abs(daemon("r_shoulder_pitch") - wanted) < 1e-6
            await pilot.press("0")
            await until(pilot, lambda: daemon("r_shoulder_pitch") == 0.0, "reset")
            await pilot.press("escape")
            await until(pilot, lambda: not isinstance(app.screen, CalibrationScreen), "back")
