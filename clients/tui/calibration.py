"""Joint offsets (admin only): a screen opened from the Pose tab with ``o``.

It puts the robot in ROBOTIS's offset-tuner posture (every joint at zero, ``p``), then the user
picks a joint (up/down) and nudges its offset (``+``/``-`` one servo step, 0.088°; ``]``/``[``
ten steps) while the table shows, live, each joint's offset and its present angle; ``m`` mirrors
the joint's offset to its partner on the other side, ``u`` undoes the last change, ``0`` resets
the joint, ``w`` writes every offset to the user config (:mod:`config.user_file`). Each change is
sent at once with the ``offsets`` verb (admin, with the lease: ``l``), and the daemon applies it
to the next goal. The editing logic is the notebook client's
(:class:`clients.calibration.OffsetEdits`).
"""

from __future__ import annotations

import math
from typing import Any

from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import DataTable, Label

from clients.calibration import OffsetEdits
from clients.tui.i18n import N_, _
from clients.tui.model import Model
from clients.tui.tabs.base import TabView, put_cell
from clients.tui.widgets.keybar import KeyBar
from config.loader import RobotConfig
from config.user_file import set_joint_offsets
from schemas import units
from schemas.errors import ConfigError
from schemas.roles import Role

STEP_DEG = units.DEG_PER_UNIT  # one servo step, as ROBOTIS's tuner nudges


class CalibrationView(TabView):
    TAB_ID = "calibration"
    WATCHES = ("joints",)
    DEFAULT_CSS = """
    CalibrationView #cal-table { height: 1fr; }
    """
    ACTION_ROLES = {a: Role.ADMIN for a in ("nudge", "mirror", "undo", "zero", "posture", "save")}
    BINDINGS = [
        Binding("p", "posture", N_("Reference posture")),
        Binding("plus,equals_sign", "nudge(1)", N_("Offset +1 step")),
        Binding("minus", "nudge(-1)", N_("Offset −1 step")),
        Binding("right_square_bracket", "nudge(10)", N_("Offset +10 steps"), show=False),
        Binding("left_square_bracket", "nudge(-10)", N_("Offset −10 steps"), show=False),
        Binding("m", "mirror", N_("Mirror to the other side")),
        Binding("u", "undo", N_("Undo")),
        Binding("0", "zero", N_("Offset to 0")),
        Binding("w", "save", N_("Save to the config")),
    ]

    def __init__(self, model: Model, robot: RobotConfig, save_path: str | None = None) -> None:
        super().__init__(model)
        self.robot = robot
        self.edits = OffsetEdits({j.name: j.offset_deg for j in robot.joints})
        self.save_path = save_path
        self.saved_to = ""

    def compose(self) -> ComposeResult:
        hint = _("Joint offsets: put the robot on a stand, take the lease (l).")
        yield Label(hint, classes="bar")
        table: DataTable[str] = DataTable(id="cal-table", cursor_type="row")
        table.add_column(_("joint"), key="name", width=18)
        table.add_column(_("offset°"), key="offset", width=8)
        table.add_column(_("present°"), key="present", width=9)
        for j in self.robot.joints:
            table.add_row(j.name, "", "", key=j.name)
        yield table

    def on_mount(self) -> None:
        self.send("offsets", tag="get", quiet=True, op="get")
        self.refresh_view(self.model)
        # The app's render timer draws the main screen's tab; this screen draws itself.
        self._drawn = -1
        self.set_interval(1 / 10, self._redraw)

    def _redraw(self) -> None:
        version = self.model.versions.get("joints", 0)
        if version != self._drawn:
            self._drawn = version
            self.refresh_view(self.model)

    def focus_target(self) -> DataTable[str]:
        return self.query_one(DataTable)

    @property
    def selected(self) -> str:
        table = self.query_one(DataTable)
        row = table.coordinate_to_cell_key(table.cursor_coordinate).row_key
        return str(row.value)

    def refresh_view(self, model: Model) -> None:
        table = self.query_one(DataTable)
        present: dict[str, float] = {}
        if model.joints is not None:
            present = {
                n: math.degrees(p)
                for n, p in zip(model.joints.name, model.joints.position, strict=False)
            }
        for name, deg in self.edits.offsets.items():
            put_cell(table, name, "offset", f"{deg:+.3f}")
            now = present.get(name)
            put_cell(table, name, "present", "—" if now is None else f"{now:+.1f}")

    # -- actions ---------------------------------------------------------------------------------
    def _set(self, changes: dict[str, float]) -> None:
        if changes:
            self.send("offsets", tag="set", op="set", offsets=changes)

    def action_nudge(self, steps: int) -> None:
        self._set(self.edits.nudge(self.selected, steps * STEP_DEG))

    def action_mirror(self) -> None:
        try:
            self._set(self.edits.mirror(self.selected))
        except ValueError as exc:
            self.notify_error(str(exc))

    def action_undo(self) -> None:
        try:
            self._set(self.edits.undo())
        except ValueError:
            self.notify_error(_("Nothing to undo."))

    def action_zero(self) -> None:
        self._set(self.edits.reset([self.selected]))

    def action_posture(self) -> None:
        positions = {j.name: 0.0 for j in self.robot.joints}
        self.send("pose", tag="posture", positions=positions, duration=2.0)

    def action_save(self) -> None:
        try:
            path = set_joint_offsets(self.edits.offsets, self.save_path)
        except ConfigError as exc:
            self.notify_error(str(exc))
            return
        self.saved_to = str(path)
        self.app.notify(_("Offsets saved to {path}").format(path=path))

    def command_done(self, tag: str, applied: dict[str, Any], error: str) -> None:
        if error:
            if tag == "set":
                self.edits.refused()
                if self.edits.pending:  # what the daemon holds is known once they are answered
                    self.send("offsets", tag="get", quiet=True, op="get")
                self.refresh_view(self.model)
            self.notify_error(error)
            return
        if tag in ("get", "set") and "offsets" in applied:
            self.edits.applied(applied["offsets"], answers_change=tag == "set")
            self.refresh_view(self.model)


class CalibrationScreen(Screen[None]):
    """The calibration view over the main screen; escape goes back."""

    BINDINGS = [Binding("escape", "app.pop_screen", N_("Back"))]

    def __init__(self, model: Model, robot: RobotConfig, save_path: str | None = None) -> None:
        super().__init__()
        self.view = CalibrationView(model, robot, save_path)

    def compose(self) -> ComposeResult:
        yield self.view
        yield KeyBar()

    def on_mount(self) -> None:
        self.view.focus_target().focus()
