"""IMU: accelerometer and gyroscope plots (x/y/z toggles, time window zoom) and fall state."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.widgets import Checkbox, Static

from clients.tui.i18n import N_, _
from clients.tui.model import Model
from clients.tui.tabs.base import TabView, show_text
from clients.tui.widgets.plot import Plot, Series

AXES = ("x", "y", "z")
COLOURS = ("red1", "green1", "dodger_blue1")


class ImuTab(TabView):
    TAB_ID = "imu"
    WATCHES = ("imu",)
    DEFAULT_CSS = """
    ImuTab #imu-fall { width: auto; }
    """
    BINDINGS = [
        Binding("x", "toggle_axis('accel', 0)", N_("accel x"), show=False),
        Binding("y", "toggle_axis('accel', 1)", N_("accel y"), show=False),
        Binding("z", "toggle_axis('accel', 2)", N_("accel z"), show=False),
        Binding("X", "toggle_axis('gyro', 0)", N_("gyro x"), show=False),
        Binding("Y", "toggle_axis('gyro', 1)", N_("gyro y"), show=False),
        Binding("Z", "toggle_axis('gyro', 2)", N_("gyro z"), show=False),
        Binding("plus,equals_sign", "zoom(-1)", N_("Zoom in")),
        Binding("minus", "zoom(1)", N_("Zoom out")),
    ]

    def compose(self) -> ComposeResult:
        with Horizontal(classes="bar"):
            yield self.stream_box()
            for kind in ("accel", "gyro"):
                for axis in AXES:
                    yield Checkbox(f"{kind[0]}{axis}", True, id=f"{kind}-{axis}", compact=True)
            yield Static("", id="imu-fall")
        yield Plot(_("Accelerometer"), "m/s²", id="accel-plot")
        yield Plot(_("Gyroscope"), "rad/s", id="gyro-plot")

    def on_mount(self) -> None:
        self.refresh_view(self.model)

    def action_toggle_axis(self, kind: str, axis: int) -> None:
        box = self.query_one(f"#{kind}-{AXES[axis]}", Checkbox)
        box.value = not box.value

    def action_zoom(self, step: int) -> None:
        for plot in self.query(Plot):
            plot.zoom(step)

    def on_checkbox_changed(self, event: Checkbox.Changed) -> None:
        self.refresh_view(self.model)

    def refresh_view(self, model: Model) -> None:
        hist = list(model.imu_hist)
        times = [t for t, _a, _g in hist]
        for kind in ("accel", "gyro"):
            series = []
            for i, axis in enumerate(AXES):
                values = [(a if kind == "accel" else g)[i] for _t, a, g in hist]
                visible = self.query_one(f"#{kind}-{axis}", Checkbox).value
                series.append(Series(axis, COLOURS[i], times, values, visible))
            self.query_one(f"#{kind}-plot", Plot).show(series)
        fall = model.imu.fall if model.imu else "—"
        style = "bold red" if fall not in ("none", "—") else "green"
        words = {
            "none": _("upright"),
            "forward": _("fallen forward"),
            "backward": _("fallen backward"),
        }
        show_text(
            self.query_one("#imu-fall", Static), f"{_('fall')}: [{style}]{words.get(fall, fall)}[/]"
        )
