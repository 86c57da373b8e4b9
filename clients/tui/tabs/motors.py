"""Motors: all 20 joints in a table updated in place, two chosen joints plotted side by side,
goal steps and typed goals, torque on/off."""

from __future__ import annotations

import math
from typing import Any

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.widgets import DataTable, Input, Label

from clients.tui.i18n import N_, _
from clients.tui.model import Model
from clients.tui.tabs.base import TabView, put_cell
from clients.tui.widgets.plot import Plot, Series
from config.loader import RobotConfig
from schemas.roles import Role

# key, title, width (cells): fixed so updates never re-measure the table.
COLUMNS: tuple[tuple[str, str, int], ...] = (
    ("id", N_("id"), 2),
    ("name", N_("joint"), 16),
    ("pos", N_("pos°"), 6),
    ("goal", N_("goal°"), 6),
    ("speed", N_("rad/s"), 5),
    ("load", N_("load%"), 5),
    ("temp", N_("°C"), 3),
    ("volt", N_("V"), 4),
    ("torque", N_("torque"), 6),
    ("online", N_("online"), 6),
    ("alarm", N_("alarm"), 5),
)


def cells(joints: Any, i: int) -> dict[str, str]:
    """The table cells of joint ``i`` of a ``Joints`` message."""
    return {
        "pos": f"{math.degrees(joints.position[i]):6.1f}",
        "goal": f"{math.degrees(joints.goal[i]):6.1f}",
        "speed": f"{joints.velocity[i]:5.2f}",
        "load": f"{joints.load[i] * 100:5.0f}",
        "temp": f"{joints.temperature[i]:3.0f}",
        "volt": f"{joints.voltage[i]:4.1f}",
        "torque": _("on") if joints.torque_enabled[i] else _("off"),
        "online": "✓" if joints.online[i] else "✗",
        "alarm": f"0x{joints.alarm[i]:02X}" if joints.alarm[i] else "",
    }


class MotorsTab(TabView):
    TAB_ID = "motors"
    WATCHES = ("joints",)
    DEFAULT_CSS = """
    MotorsTab DataTable { height: 1fr; min-height: 6; }
    MotorsTab #motor-plots { height: 1fr; min-height: 6; }
    MotorsTab #goal-input { width: 12; }
    """
    ACTION_ROLES = {"step": Role.OPERATOR, "torque": Role.OPERATOR, "type_goal": Role.OPERATOR}
    BINDINGS = [
        Binding("left_square_bracket", "step(-1)", N_("Goal −1°")),
        Binding("right_square_bracket", "step(1)", N_("Goal +1°")),
        Binding("left_curly_bracket", "step(-10)", N_("Goal −10°"), show=False),
        Binding("right_curly_bracket", "step(10)", N_("Goal +10°"), show=False),
        Binding("t", "torque", N_("Torque on/off")),
        Binding("g", "type_goal", N_("Type goal")),
        Binding("a", "plot('a')", N_("Plot A")),
        Binding("b", "plot('b')", N_("Plot B")),
    ]

    def __init__(self, model: Model, robot: RobotConfig) -> None:
        super().__init__(model)
        self.robot = robot
        self.plotted = {"a": robot.ids[0], "b": robot.ids[1]}

    def compose(self) -> ComposeResult:
        with Horizontal(classes="bar"):
            yield self.stream_box()
            yield Label(_("goal° of the selected joint:"))
            yield Input(placeholder="0.0", id="goal-input", type="number", compact=True)
        table: DataTable[str] = DataTable(id="joint-table", cursor_type="row", zebra_stripes=True)
        for key, title, width in COLUMNS:
            table.add_column(_(title), key=key, width=width)
        for jid in self.robot.ids:
            empty = {k: "" for k, _t, _w in COLUMNS}
            empty.update(id=str(jid), name=self.robot.joint(jid).name)
            table.add_row(*[empty[k] for k, _t, _w in COLUMNS], key=str(jid))
        yield table
        with Horizontal(id="motor-plots"):
            yield Plot("", "°", id="plot-a")
            yield Plot("", "°", id="plot-b")

    def on_mount(self) -> None:
        self.refresh_view(self.model)

    def focus_target(self) -> DataTable[str]:
        return self.query_one(DataTable)

    @property
    def selected(self) -> int:
        table = self.query_one(DataTable)
        row = table.coordinate_to_cell_key(table.cursor_coordinate).row_key
        return int(row.value or self.robot.ids[0])

    def refresh_view(self, model: Model) -> None:
        table = self.query_one(DataTable)
        joints = model.joints
        if joints is not None:
            for i, jid in enumerate(joints.id):
                if str(jid) not in table.rows:
                    continue
                for key, value in cells(joints, i).items():
                    put_cell(table, str(jid), key, value)
        hist = list(model.joint_hist)
        times = [t for t, _p in hist]
        for slot, jid in self.plotted.items():
            plot = self.query_one(f"#plot-{slot}", Plot)
            plot.border_title = f"{slot.upper()}: {jid} {self.robot.joint(jid).name}"
            col = model.joint_index(jid)
            values = [p[col] for _t, p in hist] if col is not None else []
            plot.show([Series(_("position"), "yellow", times if values else [], values)])

    # -- actions ---------------------------------------------------------------------------------
    def action_step(self, degrees: float) -> None:
        jid = self.selected
        goal = self.model.goal_deg(jid)
        if goal is None:
            self.notify_error(_("No joint data yet: cannot step the goal."))
            return
        self.set_goal(jid, goal + degrees)

    def set_goal(self, jid: int, degrees: float) -> None:
        joint = self.robot.joint(jid)
        if not joint.min_deg <= degrees <= joint.max_deg:
            self.notify_error(
                _("{name}: {value:.1f}° is outside {lo:.0f}…{hi:.0f}°").format(
                    name=joint.name, value=degrees, lo=joint.min_deg, hi=joint.max_deg
                )
            )
            return
        self.send("joint", tag="motors", quiet=True, id=jid, position=math.radians(degrees))

    def action_torque(self) -> None:
        jid = self.selected
        i = self.model.joint_index(jid)
        on = bool(self.model.joints and i is not None and self.model.joints.torque_enabled[i])
        self.send("torque", tag="motors", enable=not on, ids=[jid])

    def action_type_goal(self) -> None:
        self.query_one("#goal-input", Input).focus()

    def action_plot(self, slot: str) -> None:
        self.plotted[slot] = self.selected
        self.refresh_view(self.model)

    def on_input_submitted(self, event: Input.Submitted) -> None:
        degrees = self.typed_degrees(event.value)
        if degrees is None:
            return
        self.set_goal(self.selected, degrees)
        self.query_one(DataTable).focus()

    def command_done(self, tag: str, applied: dict[str, Any], error: str) -> None:
        if error:
            self.notify_error(error)
