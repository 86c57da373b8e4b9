"""Actions: the action-page library (``pages`` verb) as a list, opening a page to edit, play,
stop, delete. Editing a page and teach mode are :class:`clients.tui.tabs.page_edit.PageEditView`,
which this tab extends.
"""

from __future__ import annotations

import contextlib
from typing import Any

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.widgets import DataTable, Input, Label

from clients.pages import blank_page
from clients.tui.i18n import N_, _
from clients.tui.messages import LinkState
from clients.tui.model import Model
from clients.tui.tabs.page_edit import ActionsState, ConfirmScreen, PageEditView

__all__ = ["ActionsState", "ActionsTab", "ConfirmScreen"]

NEW_FROM = 100  # new pages take the first free number from here
LIST_COLUMNS = (
    ("number", N_("page"), 4),
    ("name", N_("name"), 14),
    ("steps", N_("steps"), 5),
    ("repeat", N_("repeat"), 6),
    ("speed", N_("speed"), 5),
    ("next", N_("next"), 4),
    ("exit", N_("exit"), 4),
    ("origin", N_("origin"), 10),
)


class ActionsTab(PageEditView):
    """The Actions tab: the page list and the player around the page editor."""

    TAB_ID = "actions"
    WATCHES = ("status", "link", "joints")
    DEFAULT_CSS = """
    ActionsTab DataTable { height: 1fr; }
    ActionsTab #actions-page-info { height: 1; padding: 0 1; }
    ActionsTab #actions-input { width: 1fr; }
    """
    BINDINGS = [
        Binding("escape", "back", N_("Back / end teach")),
        Binding("n", "new", N_("New page")),
        Binding("r", "refresh", N_("Refresh")),
        Binding("ctrl+s", "save", N_("Save")),
        Binding("u,ctrl+z", "undo", N_("Undo")),
        Binding("left_square_bracket", "nudge(-1)", N_("Value −1")),
        Binding("right_square_bracket", "nudge(1)", N_("Value +1")),
        Binding("left_curly_bracket", "nudge(-10)", N_("Value −10"), show=False),
        Binding("right_curly_bracket", "nudge(10)", N_("Value +10"), show=False),
        Binding("e", "type('value')", N_("Type value")),
        Binding("f", "type('field')", N_("Page field")),
        Binding("i", "insert", N_("Insert step")),
        Binding("d", "duplicate", N_("Duplicate step")),
        Binding("x,delete", "delete", N_("Delete")),
        Binding("shift+up,K", "move(-1)", N_("Step up")),
        Binding("shift+down,J", "move(1)", N_("Step down")),
        Binding("m", "mirror('right')", N_("Mirror right → left")),
        Binding("M", "mirror('swap')", N_("Mirror swap sides")),
        Binding("t", "limp('joint')", N_("Limp joint")),
        Binding("a", "limp('limb')", N_("Limp arm/leg/head")),
        Binding("A", "limp('all')", N_("Limp all")),
        Binding("k", "capture", N_("Capture")),
        Binding("comma", "by_hand(-1)", N_("Push by hand −"), show=False),
        Binding("full_stop", "by_hand(1)", N_("Push by hand +"), show=False),
        Binding("p", "play(False)", N_("Play")),
        Binding("P", "play(True)", N_("Play from step")),
        Binding("g", "go_step", N_("Go to step")),
        Binding("o", "stop('stop')", N_("Stop")),
        Binding("b", "stop('brake')", N_("Brake")),
    ]

    # -- layout ----------------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        with Horizontal(classes="bar"):
            yield self.stream_box()
            yield Label("", id="actions-status")
        yield Label("", id="actions-page-info")
        listing: DataTable[str] = DataTable(id="pages-list", cursor_type="row", zebra_stripes=True)
        for key, title, width in LIST_COLUMNS:
            listing.add_column(_(title), key=key, width=width)
        yield listing
        page: DataTable[str] = DataTable(id="page-table", cursor_type="cell", zebra_stripes=True)
        page.fixed_columns = 3  # step, time, pause stay in view while the joints scroll
        yield page
        yield Input(id="actions-input", compact=True)

    def on_mount(self) -> None:
        self.query_one("#actions-input", Input).display = False
        self.show_listing()
        self.show_page()

    def focus_target(self) -> DataTable[str]:
        return self.query_one("#page-table" if self.st.editor else "#pages-list", DataTable)

    # -- drawing ---------------------------------------------------------------------------------
    def refresh_view(self, model: Model) -> None:
        # self.app is the DarwinApp, which holds the link's state.
        connected = self.app.link_info.state is LinkState.CONNECTED  # type: ignore[attr-defined]
        if not self.st.requested and connected:
            self.st.requested = True
            self.action_refresh()
        self.show_status()

    def show_listing(self) -> None:
        table = self.query_one("#pages-list", DataTable)
        table.clear()
        for row in self.st.listing:
            table.add_row(*[str(row.get(k, "")) for k, _t, _w in LIST_COLUMNS],
                          key=str(row["number"]))
        with contextlib.suppress(Exception):
            table.move_cursor(row=min(self.st.row, max(len(self.st.listing) - 1, 0)))

    # -- where the cursor is -------------------------------------------------------------------
    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if event.data_table.id == "pages-list":
            self.st.row = event.cursor_row

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        if event.data_table.id == "pages-list" and event.row_key.value:
            self.send("pages", tag="get", op="get", number=int(event.row_key.value))

    # -- browsing --------------------------------------------------------------------------------
    def action_refresh(self) -> None:
        self.send("pages", tag="list", quiet=True, op="list")

    def action_new(self) -> None:
        used = {row["number"] for row in self.st.listing}
        number = next((n for n in range(NEW_FROM, 256) if n not in used), 255)
        self.open(blank_page(number, _("new {n}").format(n=number)))
        self._edit(lambda e: e.insert_step(0, self.present() or {}))

    def action_back(self) -> None:
        box = self.query_one("#actions-input", Input)
        if box.display:
            box.display = False
            self.focus_target().focus()
            return
        if self.st.limp:
            self.end_teach()
            return
        if self.editor is not None:
            if self.editor.dirty and not self.st.warned:
                self.st.warned = True
                self.app.notify(_("Unsaved changes: Ctrl+S saves them, Esc again drops them."))
                return
            self.st.editor, self.st.warned = None, False
            self.show_page()
            self.focus_target().focus()
            self.action_refresh()

    def action_delete(self) -> None:
        if self.editor is not None:
            self._edit(lambda e: e.delete_step(self.st.row))
            return
        if self.st.listing:
            row = self.st.listing[min(self.st.row, len(self.st.listing) - 1)]
            number = row["number"]

            def go(yes: bool | None) -> None:
                if yes:
                    self.send("pages", tag="delete", op="delete", number=number)

            question = _("Delete page {number} ({name}) from your motion library?").format(
                number=number, name=row["name"]
            )
            self.app.push_screen(ConfirmScreen(question), go)

    # -- robot -----------------------------------------------------------------------------------
    def action_play(self, from_step: bool) -> None:
        if self.editor is not None:
            number = self.editor.page["number"]
            if self.editor.dirty:
                self.notify_error(_("Save the page (Ctrl+S) before playing it."))
                return
        elif self.st.listing:
            number = self.st.listing[min(self.st.row, len(self.st.listing) - 1)]["number"]
        else:
            return
        step = self.st.row + 1 if from_step and self.editor is not None else 1
        self.send("pages", tag="play", op="play", number=number, step=step)

    def action_stop(self, how: str) -> None:
        self.send("action", tag="stop", op=how)

    def command_done(self, tag: str, applied: dict[str, Any], error: str) -> None:
        if error:
            if tag in ("limp",):
                self.st.limp = []
                self.show_status()
            if tag != "list":
                self.notify_error(error)
            return
        if tag == "list":
            self.st.listing = list(applied.get("pages", []))
            self.show_listing()
        elif tag == "get":
            self.open(applied.get("page", {}))
        elif tag == "put":
            if self.editor is not None:
                self.editor.dirty = False
            self.app.notify(_("Saved page {number} to {path}").format(
                number=applied.get("number"), path=applied.get("path")))
            self.show_page()
            self.action_refresh()
        elif tag == "delete":
            self.app.notify(_("Deleted page {number}").format(number=applied.get("number")))
            self.action_refresh()
