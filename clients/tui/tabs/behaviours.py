"""Behaviours: the library (``behaviours`` verb) on the left, the choreography on the right;
add, remove, reorder, walk durations, play/stop with the playing item marked; LED colours;
choreographies saved to and loaded from JSON files."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Input, Label, OptionList
from textual.widgets.option_list import Option

from clients.tui.i18n import N_, _, language
from clients.tui.model import Model
from clients.tui.tabs.base import TabView
from clients.tui.widgets.colours import ColourPicker
from schemas.roles import Role

DURATION_STEP_S = 0.5
DEFAULT_WALK_S = 3.0
FILE_FORMAT = "darwin-choreography"


def library_entries(applied: dict[str, Any]) -> list[dict[str, Any]]:
    """Normalise the ``behaviours`` reply into a list of ``{"id", "name", "kind", …}``."""
    raw = applied.get("behaviours", applied.get("library", []))
    if isinstance(raw, dict):
        raw = [
            {"id": k, **(v if isinstance(v, dict) else {"name": str(v)})} for k, v in raw.items()
        ]
    out = []
    for entry in raw if isinstance(raw, list) else []:
        if isinstance(entry, dict) and "id" in entry:
            out.append({"name": str(entry.get("name", entry["id"])), **entry})
    return out


def choreography_state(status: Any) -> dict[str, Any]:
    """The choreography player's state: ``status.choreography``, or its motion module's."""
    if status is None:
        return {}
    return status.choreography or status.motion.get("choreography") or {}


def playing_index(choreography: dict[str, Any]) -> int | None:
    if not choreography or not choreography.get("playing", choreography.get("running", True)):
        return None
    for key in ("index", "current", "item"):
        value = choreography.get(key)
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    return None


class BehavioursTab(TabView):
    TAB_ID = "behaviours"
    WATCHES = ("status", "library")
    DEFAULT_CSS = """
    BehavioursTab .column { width: 1fr; }
    BehavioursTab OptionList { height: 1fr; }
    BehavioursTab #chor-file { width: 1fr; }
    BehavioursTab #chor-duration { width: 8; }
    """
    _library_version = -1  # the model version last drawn
    ACTION_ROLES = {"play": Role.OPERATOR, "stop": Role.OPERATOR}
    BINDINGS = [
        Binding("enter", "add", N_("Add"), show=False),
        Binding("delete,backspace", "remove", N_("Remove")),
        Binding("shift+up,K", "move(-1)", N_("Move up")),
        Binding("shift+down,J", "move(1)", N_("Move down")),
        Binding("plus,equals_sign", "duration(1)", N_("Longer"), show=False),
        Binding("minus", "duration(-1)", N_("Shorter"), show=False),
        Binding("p", "play", N_("Play")),
        Binding("o", "stop", N_("Stop")),
        Binding("ctrl+s", "save", N_("Save")),
        Binding("ctrl+o", "load", N_("Load")),
    ]

    def compose(self) -> ComposeResult:
        with Horizontal(classes="bar"):
            yield self.stream_box()
            yield ColourPicker(_("eyes"), id="led-eye")
            yield ColourPicker(_("forehead"), id="led-head")
        with Horizontal():
            with Vertical(classes="column"):
                yield OptionList(id="library")
            with Vertical(classes="column"):
                yield OptionList(id="choreography")
                with Horizontal(classes="bar"):
                    yield Label(_("walk s"))
                    yield Input(id="chor-duration", type="number", compact=True)
                    yield Input(
                        "choreography.json", id="chor-file", compact=True, placeholder=_("file")
                    )

    def on_mount(self) -> None:
        self.query_one("#library").border_title = _("Library")
        self.query_one("#choreography").border_title = _("Choreography")
        self.refresh_view(self.model)

    def focus_target(self) -> OptionList:
        return self.query_one("#library", OptionList)

    # -- views -----------------------------------------------------------------------------------
    def show_library(self) -> None:
        library = self.query_one("#library", OptionList)
        library.clear_options()
        for entry in self.model.edits.behaviours:
            kind = entry.get("kind", "")
            library.add_option(Option(Text.assemble(self.name_of(entry), (f"  {kind}", "dim"))))
        if self.model.edits.behaviours:
            library.highlighted = 0

    @staticmethod
    def name_of(entry: dict[str, Any]) -> str:
        """The behaviour's name in the UI's language when the library has one."""
        return str(entry.get(f"name_{language()}") or entry["name"])

    def label(self, item: dict[str, Any]) -> str:
        names = {e["id"]: self.name_of(e) for e in self.model.edits.behaviours}
        text = str(names.get(item.get("behaviour"), item.get("behaviour")))
        if "duration" in item:
            text += f"  {item['duration']:g} s"
        return text

    def show_choreography(self) -> None:
        chor = self.query_one("#choreography", OptionList)
        keep = chor.highlighted
        playing = playing_index(choreography_state(self.model.status))
        chor.clear_options()
        for i, item in enumerate(self.model.edits.choreography):
            if i == playing:
                chor.add_option(Option(Text("▶ " + self.label(item), style="bold reverse green")))
            else:
                chor.add_option(Option(f"{i + 1:2}. {self.label(item)}"))
        n = len(self.model.edits.choreography)
        if n:
            chor.highlighted = min(keep or 0, n - 1)
        chor.border_subtitle = _("playing") if playing is not None else ""

    def refresh_view(self, model: Model) -> None:
        if model.version("library") != self._library_version:
            self._library_version = model.version("library")
            self.show_library()
        self.show_choreography()

    # -- editing ---------------------------------------------------------------------------------
    def action_add(self) -> None:
        library = self.query_one("#library", OptionList)
        if library.highlighted is None or not self.model.edits.behaviours:
            return
        entry = self.model.edits.behaviours[library.highlighted]
        item: dict[str, Any] = {"behaviour": entry["id"]}
        if entry.get("kind") in ("walk", "pause"):
            item["duration"] = float(entry.get("duration", DEFAULT_WALK_S))
        for key in ("x", "y", "turn"):
            if key in entry:
                item[key] = entry[key]
        self.model.edits.choreography.append(item)
        self.show_choreography()
        chor = self.query_one("#choreography", OptionList)
        chor.highlighted = len(self.model.edits.choreography) - 1

    def on_option_list_option_selected(self, event: OptionList.OptionSelected) -> None:
        if event.option_list.id == "library":
            self.action_add()

    def _selected(self) -> int | None:
        chor = self.query_one("#choreography", OptionList)
        n = len(self.model.edits.choreography)
        i = chor.highlighted
        return i if i is not None and 0 <= i < n else None

    def action_remove(self) -> None:
        i = self._selected()
        if i is not None:
            del self.model.edits.choreography[i]
            self.show_choreography()

    def action_move(self, step: int) -> None:
        i = self._selected()
        items = self.model.edits.choreography
        if i is None or not 0 <= i + step < len(items):
            return
        items[i], items[i + step] = items[i + step], items[i]
        self.show_choreography()
        self.query_one("#choreography", OptionList).highlighted = i + step

    def action_duration(self, step: int) -> None:
        i = self._selected()
        if i is None or "duration" not in self.model.edits.choreography[i]:
            return
        item = self.model.edits.choreography[i]
        item["duration"] = max(DURATION_STEP_S, item["duration"] + step * DURATION_STEP_S)
        self.show_choreography()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        if event.input.id == "chor-duration":
            i = self._selected()
            try:
                seconds = float(event.value)
            except ValueError:
                seconds = 0.0
            if i is None or "duration" not in self.model.edits.choreography[i]:
                self.notify_error(_("Select a walk or pause item to set its duration."))
            elif seconds <= 0:
                self.notify_error(_("The time must be a number of seconds above 0."))
            else:
                self.model.edits.choreography[i]["duration"] = seconds
                self.show_choreography()
        elif event.input.id == "chor-file":
            self.action_save()

    # -- robot -----------------------------------------------------------------------------------
    def action_play(self) -> None:
        if not self.model.edits.choreography:
            self.notify_error(_("The choreography is empty: add behaviours from the library."))
            return
        self.send("choreography", tag="play", op="play", items=list(self.model.edits.choreography))

    def action_stop(self) -> None:
        self.send("choreography", tag="play", op="stop")

    def on_colour_picker_picked(self, event: ColourPicker.Picked) -> None:
        part = "eye" if event.picker.id == "led-eye" else "head"
        self.send("led", tag="led", quiet=True, **{part: list(event.rgb)})

    # -- files -----------------------------------------------------------------------------------
    def _path(self) -> Path:
        return Path(self.query_one("#chor-file", Input).value.strip() or "choreography.json")

    def action_save(self) -> None:
        path = self._path()
        items = self.model.edits.choreography
        doc = {"format": FILE_FORMAT, "version": 1, "items": items}
        try:
            path.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
        except OSError as exc:
            self.notify_error(_("Cannot save {path}: {error}").format(path=path, error=exc))
            return
        self.app.notify(_("Saved {n} items to {path}").format(n=len(items), path=path))

    def action_load(self) -> None:
        path = self._path()
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
            items = doc["items"] if isinstance(doc, dict) else None
            if not isinstance(items, list) or not all(
                isinstance(i, dict) and "behaviour" in i for i in items
            ):
                raise ValueError(_("no list of items with a 'behaviour' each"))
        except (OSError, ValueError, KeyError) as exc:
            self.notify_error(_("Cannot load {path}: {error}").format(path=path, error=exc))
            return
        self.model.edits.choreography = items
        self.show_choreography()
        self.app.notify(_("Loaded {n} items from {path}").format(n=len(items), path=path))

    def command_done(self, tag: str, applied: dict[str, Any], error: str) -> None:
        if error:
            self.notify_error(error)
