"""Walk: WASD / arrows to walk (forward, back, sideways), Q/E to turn, space to stop; ball play
start/stop with its phase; the gait parameters as an editable form (``walk_params``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.widget import Widget
from textual.widgets import Button, Input, Label, Static

from clients.tui.i18n import N_, _
from clients.tui.model import Model
from clients.tui.tabs.base import TabView, role_at_least, show_text
from schemas.gait import gait_label
from schemas.roles import Role

STEP_X = 0.02  # m/s per key press
STEP_Y = 0.02  # m/s
STEP_TURN = 0.1  # rad/s


def describe(value: Any) -> str:
    """A status sub-map in a few words (the daemon decides what it holds)."""
    if isinstance(value, dict):
        return ", ".join(
            f"{k} {v:.2f}" if isinstance(v, float) else f"{k} {v}" for k, v in value.items()
        )
    if isinstance(value, bool):
        return _("on") if value else _("off")
    return "—" if value in (None, "") else str(value)


def walking_state(motion: Mapping[str, Any]) -> str:
    """The walking module's status (``status.motion["walking"]``) in a few words."""
    state = motion.get("walking", motion.get("walk"))
    if not isinstance(state, dict):
        return describe(state)
    if not state.get("walking"):
        return _("stopped")
    speed = state.get("speed", {})
    words = f"x {speed.get('x', 0.0):+.2f} y {speed.get('y', 0.0):+.2f} m/s, " + _("turn")
    words += f" {speed.get('turn', 0.0):+.2f} rad/s"
    return words + (" (" + _("stopping") + ")" if state.get("stopping") else "")


def ball_phase(motion: Mapping[str, Any]) -> str:
    ball = motion.get("ball", motion.get("playball"))
    if isinstance(ball, dict):
        if not ball.get("active", ball.get("running", True)):
            return ""
        return str(ball.get("phase") or "on")
    return "" if ball in (None, False) else str(ball)


class WalkTab(TabView):
    TAB_ID = "walk"
    WATCHES = ("status", "params")
    DEFAULT_CSS = """
    WalkTab #walk-pad { width: 1fr; min-width: 34; }
    WalkTab #walk-params { width: 1fr; min-width: 34; border: round $primary-darken-2; }
    WalkTab .param { height: 1; }
    WalkTab .param Label { width: 1fr; }
    WalkTab .param Input { width: 12; }
    WalkTab Button { min-width: 0; margin-right: 1; }
    """
    _params_version = -1  # the model version last drawn
    ACTION_ROLES = {"move": Role.OPERATOR, "stop": Role.OPERATOR, "ball": Role.OPERATOR}
    BINDINGS = [
        Binding("w,up", "move(1, 0, 0)", N_("Forward")),
        Binding("s,down", "move(-1, 0, 0)", N_("Back")),
        Binding("a,left", "move(0, 1, 0)", N_("Left")),
        Binding("d,right", "move(0, -1, 0)", N_("Right")),
        Binding("q", "move(0, 0, 1)", N_("Turn left")),
        Binding("e", "move(0, 0, -1)", N_("Turn right")),
        Binding("space", "stop", N_("Stop walking")),
        Binding("b", "ball", N_("Play ball on/off")),
    ]

    def compose(self) -> ComposeResult:
        with Horizontal(classes="bar"):
            yield self.stream_box()
        with Horizontal():
            with Vertical(id="walk-pad"):
                yield Static(id="walk-keys")
                yield Static(id="walk-state")
            with Vertical(id="walk-params"):
                with Horizontal(classes="bar"):
                    yield Button(_("Read"), id="params-read", compact=True)
                    yield Button(_("Apply"), id="params-apply", compact=True, variant="primary")
                yield VerticalScroll(id="params-form")

    def on_mount(self) -> None:
        self.query_one("#walk-params").border_title = _("Gait parameters")
        self.query_one("#walk-keys", Static).update(self.keys_help())
        self.refresh_view(self.model)

    @staticmethod
    def keys_help() -> Text:
        t = Text()
        t.append("      W / ↑   " + _("forward") + "\n")
        t.append(" A / ←   D / →  " + _("sideways") + "\n")
        t.append("      S / ↓   " + _("back") + "\n")
        t.append("  Q / E  " + _("turn left / right") + "\n")
        t.append("  " + _("space") + "  " + _("stop") + "   B  " + _("play ball") + "\n")
        return t

    def build_form(self) -> None:
        form = self.query_one("#params-form", VerticalScroll)
        form.remove_children()
        rows: list[Widget] = []
        for name, value in sorted(self.model.edits.walk_params.items()):
            if isinstance(value, bool) or not isinstance(value, int | float):
                continue
            rows.append(
                Horizontal(
                    Label(gait_label(name)),
                    Input(f"{value:g}", id=f"param-{name}", type="number", compact=True),
                    classes="param",
                )
            )
        if not rows:
            rows.append(Label(_("(no parameters read yet: press Read)"), classes="param"))
        form.mount_all(rows)

    def refresh_view(self, model: Model) -> None:
        if model.version("params") != self._params_version:
            self._params_version = model.version("params")
            self.build_form()
        # Observers read the gait but may not set it (schemas.roles): Apply greys out.
        self.query_one("#params-apply", Button).disabled = not role_at_least(
            self.app, Role.OPERATOR
        )
        x, y, turn = model.edits.walk
        motion = model.status.motion if model.status else {}
        t = Text()
        t.append(_("command") + ": ", style="dim")
        t.append(f"x {x:+.2f} y {y:+.2f} m/s, " + _("turn") + f" {turn:+.2f} rad/s\n")
        t.append(_("walking") + ": ", style="dim")
        t.append(walking_state(motion) + "\n", style="bold")
        phase = ball_phase(motion)
        t.append(_("play ball") + ": ", style="dim")
        t.append((phase or _("off")) + "\n", style="bold yellow" if phase else "")
        show_text(self.query_one("#walk-state", Static), t)

    # -- actions ---------------------------------------------------------------------------------
    def action_move(self, dx: int, dy: int, dturn: int) -> None:
        x, y, turn = self.model.edits.walk
        moving = any((x, y, turn))
        x, y, turn = (
            round(x + dx * STEP_X, 3),
            round(y + dy * STEP_Y, 3),
            round(turn + dturn * STEP_TURN, 3),
        )
        self.model.edits.walk = (x, y, turn)
        op = "set" if moving else "start"
        self.send("walk", tag="walk", quiet=True, op=op, x=x, y=y, turn=turn)
        self.refresh_view(self.model)

    def action_stop(self) -> None:
        self.model.edits.walk = (0.0, 0.0, 0.0)
        self.send("walk", tag="walk", quiet=True, op="stop")
        self.refresh_view(self.model)

    def action_ball(self) -> None:
        motion = self.model.status.motion if self.model.status else {}
        op = "stop" if ball_phase(motion) else "start"
        self.send("playball", tag="ball", op=op)

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "params-read":
            self.send("walk_params", tag="walk-params")
        elif event.button.id == "params-apply":
            self.apply_params()

    def apply_params(self) -> None:
        changed: dict[str, float] = {}
        for name, old in self.model.edits.walk_params.items():
            inputs = self.query(f"#param-{name}")
            if not inputs:
                continue
            text = inputs.first(Input).value
            try:
                value = float(text)
            except ValueError:
                self.notify_error(
                    _("{name}: {value!r} is not a number").format(name=name, value=text)
                )
                return
            if value != old:
                changed[name] = int(value) if isinstance(old, int) else value
        if not changed:
            self.app.notify(_("No gait parameter changed."))
            return
        self.send("walk_params", tag="walk-params", set=changed)

    def command_done(self, tag: str, applied: dict[str, Any], error: str) -> None:
        if error:
            if tag == "walk":
                self.model.edits.walk = (0.0, 0.0, 0.0)
                self.refresh_view(self.model)
            self.notify_error(error)
            return
        if tag == "walk-params":
            params = applied.get("params", applied)
            if isinstance(params, dict) and params:
                self.model.edits.walk_params.update(params)
                self.model.bump("params")
                self.refresh_view(self.model)
