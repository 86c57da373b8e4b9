"""The help screen: every key binding of the app and of the tab that shows, translated."""

from __future__ import annotations

from collections.abc import Callable

from rich.table import Table
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Static

from clients.tui.i18n import N_, _


def binding_rows(
    bindings: list[BindingType], display: Callable[[Binding], str]
) -> list[tuple[str, str]]:
    """``(keys, what)`` rows; bindings sharing a description share a row (tabs 1 … 7)."""
    rows: dict[str, list[str]] = {}
    for b in bindings:
        if isinstance(b, Binding) and b.description:
            keys = [display(Binding(k.strip(), "")) for k in b.key.split(",")]
            rows.setdefault(_(b.description), []).extend(keys)
    return [(" / ".join(keys), what) for what, keys in rows.items()]


class HelpScreen(ModalScreen[None]):
    DEFAULT_CSS = """
    HelpScreen { align: center middle; }
    HelpScreen > VerticalScroll { width: 80; max-width: 100%; height: 90%; border: thick $primary;
        background: $surface; padding: 0 1; }
    """
    BINDINGS = [Binding("escape,q,f1,question_mark", "dismiss", N_("Close"))]

    def __init__(self, sections: list[tuple[str, list[BindingType]]]) -> None:
        super().__init__()
        self.sections = sections

    def compose(self) -> ComposeResult:
        with VerticalScroll():
            for title, bindings in self.sections:
                table = Table(title=title, show_header=False, expand=True, box=None)
                table.add_column(style="bold cyan", width=24)
                table.add_column()
                for keys, what in binding_rows(bindings, self.app.get_key_display):
                    table.add_row(keys, what)
                yield Static(table)
            yield Static(_("Esc closes this help. The mouse works too: click tabs, buttons, rows."))

    async def action_dismiss(self, result: None = None) -> None:
        self.dismiss(None)
