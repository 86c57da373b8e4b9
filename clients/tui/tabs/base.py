"""What every tab shares: a stream on/off box, a way to send commands, a render hook."""

from __future__ import annotations

from typing import Any

from textual.containers import Vertical
from textual.message import Message
from textual.visual import VisualType
from textual.widget import Widget
from textual.widgets import Checkbox, DataTable, Static

from clients.tui.i18n import _
from clients.tui.model import Model
from schemas.roles import LADDER, Role


def show_text(widget: Static, content: VisualType) -> None:
    """Put ``content`` in ``widget`` only when it differs from what it shows: ``Static.update``
    lays the whole screen out again, and a tab redrawn 15 times a second with the same words
    would pay for that every frame."""
    if widget.content != content:
        widget.update(content)


def put_cell(table: DataTable[Any], row: str, column: str, value: object) -> None:
    """Set a cell only when its value changes: any ``update_cell`` makes the table draw every
    row again, and tables redrawn 15 times a second mostly show the same numbers."""
    if table.get_cell(row, column) != value:
        table.update_cell(row, column, value)


def role_at_least(app: object, need: Role) -> bool:
    """True unless the app's link knows a role below ``need`` (unknown: everything offered)."""
    link = getattr(app, "link", None)
    role = getattr(link, "role", None)
    if role is None or role not in LADDER:
        return True
    return LADDER.index(role) >= LADDER.index(need)


class SendCommand(Message):
    """A tab asks the app to send an arbiter command (the app owns the link)."""

    def __init__(
        self,
        verb: str,
        tag: str = "",
        quiet: bool = False,
        *,
        origin: Widget | None = None,
        **fields: Any,
    ) -> None:
        super().__init__()
        self.verb = verb
        self.tag = tag
        self.quiet = quiet
        self.fields = fields
        self._origin = origin

    @property
    def control(self) -> Widget | None:
        # The tab that sent it: the app routes the reply back to its ``command_done``.
        return self._origin


class TabView(Vertical, can_focus=True):
    """Base of a tab. ``refresh_view`` is called by the app's render timer (~15 Hz) while the
    tab shows and something it draws changed; ``command_done`` gets the replies it tagged."""

    DEFAULT_CSS = """
    TabView { height: 1fr; }
    TabView .bar { height: 1; width: 1fr; }
    TabView .bar > * { margin-right: 2; }
    TabView Checkbox { border: none; padding: 0; height: 1; background: transparent; }
    """

    TAB_ID = ""
    WATCHES: tuple[str, ...] = ()  # model streams this tab draws (keys of Model.versions)
    # Actions that send commands, by the least role that may (schemas.roles): greyed out in
    # the footer when the connection's role is below.
    ACTION_ROLES: dict[str, Role] = {}

    def __init__(self, model: Model) -> None:
        super().__init__(id=self.TAB_ID)
        self.model = model
        self.ready = False  # True once mounted with its children: the timer may draw it

    def on_mount(self) -> None:
        # Textual runs this after a subclass's own on_mount (handlers follow the MRO).
        self.ready = True

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        need = self.ACTION_ROLES.get(action)
        return None if need is not None and not role_at_least(self.app, need) else True

    def stream_box(self) -> Checkbox:
        return Checkbox(_("Stream"), value=True, id=f"{self.TAB_ID}-stream", compact=True)

    @property
    def streaming(self) -> bool:
        boxes = self.query(f"#{self.TAB_ID}-stream")
        return bool(boxes) and bool(boxes.first(Checkbox).value)

    def send(self, verb: str, *, tag: str = "", quiet: bool = False, **fields: Any) -> None:
        self.post_message(SendCommand(verb, tag=tag, quiet=quiet, origin=self, **fields))

    def focus_target(self) -> Widget:
        """What gets the focus when the tab is shown (its bindings then work at once)."""
        return self

    def notify_error(self, text: str) -> None:
        self.app.notify(text, severity="error", timeout=6)

    def typed_degrees(self, text: str) -> float | None:
        """``text`` as degrees, or None once the user is told how to type them."""
        try:
            return float(text)
        except ValueError:
            self.notify_error(_("Type a number of degrees, e.g. -12.5"))
            return None

    def refresh_view(self, model: Model) -> None:
        """Draw what changed (called only while the tab shows)."""

    def command_done(self, tag: str, applied: dict[str, Any], error: str) -> None:
        """A reply to a command this tab sent with ``tag``."""
