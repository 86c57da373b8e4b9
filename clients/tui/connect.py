"""The connect screen: endpoint, robot name and your name, remembered between runs."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Grid, Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Input, Label, Static

from clients.tui.i18n import N_, _
from clients.tui.settings import Settings
from schemas.keys import check_robot_name
from schemas.session import check_endpoint


class ConnectScreen(ModalScreen[Settings | None]):
    DEFAULT_CSS = """
    ConnectScreen { align: center middle; }
    ConnectScreen > Vertical {
        width: 70; max-width: 100%; height: auto; border: thick $primary; background: $surface;
        padding: 1 2;
    }
    ConnectScreen Grid { grid-size: 2; grid-columns: 14 1fr; grid-rows: 1; grid-gutter: 1 0;
        height: auto; }
    ConnectScreen #connect-error { color: $error; height: auto; margin-top: 1; }
    ConnectScreen Horizontal { height: auto; margin-top: 1; align-horizontal: right; }
    ConnectScreen Button { margin-left: 1; }
    """
    BINDINGS = [Binding("escape", "cancel", N_("Cancel"))]

    def __init__(self, settings: Settings, detail: str = "") -> None:
        super().__init__()
        self.settings = settings
        self.detail = detail

    def compose(self) -> ComposeResult:
        with Vertical():
            yield Static(f"[b]{_('Connect to a robot')}[/b]")
            with Grid():
                yield Label(_("Endpoint"))
                yield Input(
                    self.settings.endpoint,
                    placeholder="tcp/127.0.0.1:7447",
                    id="endpoint",
                    compact=True,
                )
                yield Label(_("Robot"))
                yield Input(self.settings.robot, placeholder="op1", id="robot", compact=True)
                yield Label(_("Your name"))
                yield Input(self.settings.name, placeholder="tui", id="name", compact=True)
            yield Static(self.detail, id="connect-error")
            with Horizontal():
                yield Button(_("Cancel"), id="cancel")
                yield Button(_("Connect"), id="connect", variant="primary")

    def on_input_submitted(self) -> None:
        self.submit()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "connect":
            self.submit()
        else:
            self.dismiss(None)

    def action_cancel(self) -> None:
        self.dismiss(None)

    def submit(self) -> None:
        endpoint = self.query_one("#endpoint", Input).value.strip() or "tcp/127.0.0.1:7447"
        robot = self.query_one("#robot", Input).value.strip() or "op1"
        name = self.query_one("#name", Input).value.strip() or "tui"
        try:
            check_endpoint(endpoint)
            check_robot_name(robot)
        except ValueError as exc:
            self.query_one("#connect-error", Static).update(str(exc))
            return
        self.dismiss(Settings(endpoint, robot, name, self.settings.lang))
