"""Pose: the stick figure of the live robot; manipulate mode edits a pose, previews it on the
figure (simulate), sends it as a timed pose (apply), or goes back (reset)."""

from __future__ import annotations

import math
from typing import Any

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Button, DataTable, Input, Label

from clients.tui.i18n import N_, _
from clients.tui.model import Model
from clients.tui.tabs.base import TabView, put_cell, show_text
from clients.tui.widgets.figure import StickFigure
from config.loader import RobotConfig
from schemas.roles import Role

DEFAULT_DURATION_S = 1.0


class PoseTab(TabView):
    TAB_ID = "pose"
    WATCHES = ("joints",)
    DEFAULT_CSS = """
    PoseTab #pose-side { width: 40; }
    PoseTab #pose-table { height: 1fr; }
    PoseTab #pose-buttons { height: auto; }
    PoseTab Button { min-width: 0; margin-right: 1; }
    PoseTab #pose-duration, PoseTab #pose-value { width: 9; }
    """
    ACTION_ROLES = {"apply": Role.OPERATOR, "offsets": Role.ADMIN}
    BINDINGS = [
        Binding("m", "manipulate", N_("Monitor/Manipulate")),
        Binding("r", "get_pose", N_("Get robot pose")),
        Binding("s", "simulate", N_("Simulate")),
        Binding("p", "apply", N_("Apply")),
        Binding("z", "reset", N_("Reset")),
        Binding("left_square_bracket", "step(-5)", N_("−5°"), show=False),
        Binding("right_square_bracket", "step(5)", N_("+5°"), show=False),
        Binding("o", "offsets", N_("Joint offsets (admin)"), show=False),
    ]

    def __init__(self, model: Model, robot: RobotConfig) -> None:
        super().__init__(model)
        self.robot = robot

    def compose(self) -> ComposeResult:
        with Horizontal(classes="bar"):
            yield self.stream_box()
            yield Label("", id="pose-mode")
        with Horizontal():
            yield StickFigure(id="figure")
            with Vertical(id="pose-side"):
                table: DataTable[str] = DataTable(id="pose-table", cursor_type="row")
                table.add_column(_("joint"), key="name", width=16)
                table.add_column(_("robot°"), key="robot", width=6)
                table.add_column(_("edit°"), key="edit", width=6)
                for jid in self.robot.ids:
                    table.add_row(self.robot.joint(jid).name, "", "", key=str(jid))
                yield table
                with Horizontal(id="pose-buttons", classes="bar"):
                    yield Label(_("value°"))
                    yield Input(id="pose-value", type="number", compact=True)
                    yield Label(_("time s"))
                    yield Input(
                        str(DEFAULT_DURATION_S), id="pose-duration", type="number", compact=True
                    )
                with Horizontal(id="pose-actions", classes="bar"):
                    yield Button(_("Get"), id="pose-get", compact=True)
                    yield Button(_("Simulate"), id="pose-simulate", compact=True)
                    yield Button(_("Apply"), id="pose-apply", compact=True, variant="primary")
                    yield Button(_("Reset"), id="pose-reset", compact=True)

    def on_mount(self) -> None:
        self.refresh_view(self.model)

    def focus_target(self) -> DataTable[str]:
        return self.query_one(DataTable)

    # -- view ------------------------------------------------------------------------------------
    def refresh_view(self, model: Model) -> None:
        edits = model.edits
        live = model.positions_rad()
        figure = self.query_one(StickFigure)
        if edits.manipulate and edits.preview:
            figure.show(edits.pose, _("simulated pose (not sent)"))
        else:
            figure.show(live, _("robot (live)"))
        mode = _("manipulate") if edits.manipulate else _("monitor")
        show_text(self.query_one("#pose-mode", Label), f"{_('mode')}: [b]{mode}[/b]")
        table = self.query_one(DataTable)
        for jid in self.robot.ids:
            robot_deg = f"{math.degrees(live[jid]):6.1f}" if jid in live else ""
            edit = edits.pose.get(jid) if edits.manipulate else None
            put_cell(table, str(jid), "robot", robot_deg)
            shown = f"{math.degrees(edit):6.1f}" if edit is not None else ""
            put_cell(table, str(jid), "edit", shown)
        for button in self.query(Button):
            button.disabled = not edits.manipulate
        self.query_one("#pose-value", Input).disabled = not edits.manipulate

    @property
    def selected(self) -> int:
        table = self.query_one(DataTable)
        row = table.coordinate_to_cell_key(table.cursor_coordinate).row_key
        return int(row.value or self.robot.ids[0])

    # -- actions ---------------------------------------------------------------------------------
    def action_manipulate(self) -> None:
        edits = self.model.edits
        edits.manipulate = not edits.manipulate
        edits.preview = False
        if edits.manipulate and not edits.pose:
            self.action_get_pose()
        self.refresh_view(self.model)

    def action_get_pose(self) -> None:
        live = self.model.positions_rad()
        if not live:
            self.notify_error(_("No joint data yet: is the robot connected?"))
            return
        self.model.edits.pose = dict(live)
        self.model.edits.pose_base = dict(live)
        self.model.edits.preview = False
        self.refresh_view(self.model)

    def action_simulate(self) -> None:
        if self.model.edits.manipulate:
            self.model.edits.preview = True
            self.refresh_view(self.model)

    def action_reset(self) -> None:
        edits = self.model.edits
        edits.pose = dict(edits.pose_base)
        edits.preview = False
        self.refresh_view(self.model)

    def action_apply(self) -> None:
        edits = self.model.edits
        if not edits.manipulate or not edits.pose:
            self.notify_error(_("Press m to manipulate a pose first."))
            return
        try:
            duration = float(self.query_one("#pose-duration", Input).value)
        except ValueError:
            duration = 0.0
        if duration <= 0:
            self.notify_error(_("The time must be a number of seconds above 0."))
            return
        positions = {str(jid): rad for jid, rad in edits.pose.items()}
        self.send("pose", tag="pose", positions=positions, duration=duration)

    def action_offsets(self) -> None:
        from clients.tui.calibration import CalibrationScreen

        self.app.push_screen(CalibrationScreen(self.model, self.robot))

    def action_step(self, degrees: float) -> None:
        if not self.model.edits.manipulate:
            return
        jid = self.selected
        self.set_edit(jid, math.degrees(self.model.edits.pose.get(jid, 0.0)) + degrees)

    def set_edit(self, jid: int, degrees: float) -> None:
        joint = self.robot.joint(jid)
        clamped = max(joint.min_deg, min(joint.max_deg, degrees))
        if clamped != degrees:
            self.notify_error(
                _("{name}: {value:.1f}° is outside {lo:.0f}…{hi:.0f}°").format(
                    name=joint.name, value=degrees, lo=joint.min_deg, hi=joint.max_deg
                )
            )
        self.model.edits.pose[jid] = math.radians(clamped)
        self.refresh_view(self.model)

    def on_input_submitted(self, event: Input.Submitted) -> None:
        if event.input.id != "pose-value":
            return
        degrees = self.typed_degrees(event.value)
        if degrees is None:
            return
        self.set_edit(self.selected, degrees)

    def on_button_pressed(self, event: Button.Pressed) -> None:
        actions = {
            "pose-get": self.action_get_pose,
            "pose-simulate": self.action_simulate,
            "pose-apply": self.action_apply,
            "pose-reset": self.action_reset,
        }
        action = actions.get(event.button.id or "")
        if action is not None:
            action()

    def command_done(self, tag: str, applied: dict[str, Any], error: str) -> None:
        if error:
            self.notify_error(error)
        else:
            self.app.notify(_("Pose sent to the robot."))
