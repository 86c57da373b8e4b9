"""The connect screen: endpoint, robot name and your name, remembered between runs, and the live
robots at that endpoint to pick from (a router's endpoint lists the whole fleet)."""

from __future__ import annotations

from collections.abc import Callable

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Grid, Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Input, Label, OptionList, Static
from textual.widgets.option_list import Option
from textual.worker import Worker

from clients.fleet import RobotRecord
from clients.tui.i18n import N_, _
from clients.tui.settings import Settings
from schemas.errors import DarwinError
from schemas.keys import check_robot_name
from schemas.session import check_endpoint

# endpoint → the live robots there (clients.fleet.discover_at, or a fixed list in tests)
RobotFinder = Callable[[str], list[RobotRecord]]
# The list keeps itself live: a robot that joins (or answers late on a busy network) appears
# without F5.
REFRESH_S = 3.0


def robot_label(r: RobotRecord) -> str:
    """One robot in the list: name, state, lease holder, battery."""
    lease = r.lease_holder or _("free")
    battery = "?" if r.battery is None else f"{r.battery:.1f} V"
    alarms = _(", alarms: {n}").format(n=len(r.alarms)) if r.alarms else ""
    return _("{name}  {state}, lease {lease}, {battery}{alarms}").format(
        name=r.name, state=r.state, lease=lease, battery=battery, alarms=alarms
    )


class ConnectScreen(ModalScreen[Settings | None]):
    DEFAULT_CSS = """
    ConnectScreen { align: center middle; }
    ConnectScreen > Vertical {
        width: 70; max-width: 100%; height: auto; border: thick $primary; background: $surface;
        padding: 1 2;
    }
    ConnectScreen Grid { grid-size: 2; grid-columns: 14 1fr; grid-rows: 1; grid-gutter: 1 0;
        height: auto; }
    ConnectScreen #robots-title { margin-top: 1; }
    ConnectScreen #robots { height: auto; max-height: 8; border: none; padding: 0; }
    ConnectScreen #connect-error { color: $error; height: auto; margin-top: 1; }
    ConnectScreen Horizontal { height: auto; margin-top: 1; align-horizontal: right; }
    ConnectScreen Button { margin-left: 1; }
    """
    BINDINGS = [
        Binding("escape", "cancel", N_("Cancel")),
        Binding("f5", "find_robots", N_("Refresh the robot list")),
    ]

    def __init__(
        self, settings: Settings, detail: str = "", finder: RobotFinder | None = None
    ) -> None:
        super().__init__()
        self.settings = settings
        self.detail = detail
        self.finder = finder
        self.found: list[RobotRecord] = []
        self._finding: Worker[None] | None = None

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
            yield Static(_("Live robots (Enter connects, F5 looks again):"), id="robots-title")
            yield OptionList(id="robots")
            yield Static(self.detail, id="connect-error")
            with Horizontal():
                yield Button(_("Cancel"), id="cancel")
                yield Button(_("Connect"), id="connect", variant="primary")

    def on_mount(self) -> None:
        self.action_find_robots()
        self.set_interval(REFRESH_S, self._refresh)

    # -- the live robots ---------------------------------------------------------------------
    def action_find_robots(self) -> None:
        robots = self.query_one("#robots", OptionList)
        robots.clear_options()
        if self.finder is None:
            robots.add_option(Option(_("(no robot list without a connection)"), disabled=True))
            return
        endpoint = self.endpoint()
        try:
            check_endpoint(endpoint)
        except ValueError as exc:
            robots.add_option(Option(str(exc), disabled=True))
            return
        robots.add_option(Option(_("looking for robots at {endpoint}…").format(
            endpoint=endpoint), disabled=True))
        finder = self.finder
        self._finding = self.run_worker(
            lambda: self._find(finder, endpoint), thread=True, exclusive=True
        )

    def _refresh(self) -> None:
        """Look again quietly: the list changes only when what is found does."""
        if self.finder is None or (self._finding is not None and self._finding.is_running):
            return
        endpoint = self.endpoint()
        try:
            check_endpoint(endpoint)
        except ValueError:
            return
        finder = self.finder
        self._finding = self.run_worker(
            lambda: self._find(finder, endpoint), thread=True, exclusive=True
        )

    def _find(self, finder: RobotFinder, endpoint: str) -> None:
        """In a worker thread: discovery waits on the network."""
        try:
            found, error = finder(endpoint), ""
        except DarwinError as exc:
            found, error = [], str(exc)
        except Exception as exc:  # a session closing under us: say so, never end the UI
            found, error = [], f"{type(exc).__name__}: {exc}"
        self.app.call_from_thread(self.show_robots, endpoint, found, error)

    def show_robots(self, endpoint: str, found: list[RobotRecord], error: str = "") -> None:
        robots = self.query_one("#robots", OptionList)
        labels = [robot_label(r) for r in found]
        shown = [str(robots.get_option_at_index(i).prompt) for i in range(robots.option_count)]
        if found and not error and labels == shown:
            self.found = list(found)
            return  # nothing new: the highlight stays where the user left it
        was = robots.highlighted
        picked = (
            robots.get_option_at_index(was).id
            if was is not None and was < robots.option_count
            else None
        )
        self.found = list(found)
        robots.clear_options()
        if error or not found:
            text = error or _("no live robot at {endpoint}").format(endpoint=endpoint)
            robots.add_option(Option(text, disabled=True))
            return
        robots.add_options(Option(label, id=r.name) for r, label in zip(found, labels, strict=True))
        names = [r.name for r in found]
        current = picked if picked in names else self.query_one("#robot", Input).value.strip()
        robots.highlighted = names.index(current) if current in names else 0

    def on_option_list_option_selected(self, event: OptionList.OptionSelected) -> None:
        if event.option.id:
            self.query_one("#robot", Input).value = event.option.id
            self.submit()

    # -- connecting --------------------------------------------------------------------------
    def endpoint(self) -> str:
        return self.query_one("#endpoint", Input).value.strip() or "tcp/127.0.0.1:7447"

    def on_input_submitted(self, event: Input.Submitted) -> None:
        self.submit()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "connect":
            self.submit()
        else:
            self.dismiss(None)

    def action_cancel(self) -> None:
        self.dismiss(None)

    def submit(self) -> None:
        endpoint = self.endpoint()
        robot = self.query_one("#robot", Input).value.strip() or "op1"
        name = self.query_one("#name", Input).value.strip() or "tui"
        try:
            check_endpoint(endpoint)
            check_robot_name(robot)
        except ValueError as exc:
            self.query_one("#connect-error", Static).update(str(exc))
            return
        self.dismiss(Settings(endpoint, robot, name, self.settings.lang))
