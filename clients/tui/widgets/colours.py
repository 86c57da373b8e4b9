"""A one-line colour picker: a row of swatches, left/right to choose, enter (or a click) to
apply. Posts :class:`ColourPicker.Picked`."""

from __future__ import annotations

from rich.style import Style
from rich.text import Text
from textual import events
from textual.binding import Binding
from textual.message import Message
from textual.reactive import reactive
from textual.widget import Widget

PALETTE: tuple[tuple[str, tuple[int, int, int]], ...] = (
    ("off", (0, 0, 0)),
    ("red", (255, 0, 0)),
    ("orange", (255, 128, 0)),
    ("yellow", (255, 255, 0)),
    ("green", (0, 255, 0)),
    ("blue", (0, 0, 255)),
    ("magenta", (255, 0, 255)),
    ("white", (255, 255, 255)),
)
SWATCH = 2


class ColourPicker(Widget, can_focus=True):
    DEFAULT_CSS = """
    ColourPicker { height: 1; width: auto; }
    ColourPicker:focus { background: $boost; }
    """
    BINDINGS = [
        Binding("left", "move(-1)", "Colour", show=False),
        Binding("right", "move(1)", "Colour", show=False),
        Binding("enter", "pick", "Apply colour"),
    ]

    cursor: reactive[int] = reactive(0)

    class Picked(Message):
        def __init__(self, picker: ColourPicker, rgb: tuple[int, int, int]) -> None:
            super().__init__()
            self.picker = picker
            self.rgb = rgb

    def __init__(self, label: str, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.label = label

    def get_content_width(self, container: object, viewport: object) -> int:
        return len(self.label) + 2 + SWATCH * len(PALETTE)

    def render(self) -> Text:
        out = Text(self.label + ": ", no_wrap=True)
        for i, (_name, rgb) in enumerate(PALETTE):
            mark = "[]" if self.has_focus else "••"
            fg = "black" if sum(rgb) > 380 else "white"
            out.append(mark if i == self.cursor else "  ", Style(bgcolor=f"rgb{rgb}", color=fg))
        return out

    def action_move(self, step: int) -> None:
        self.cursor = (self.cursor + step) % len(PALETTE)

    def action_pick(self) -> None:
        self.post_message(self.Picked(self, PALETTE[self.cursor][1]))

    def on_click(self, event: events.Click) -> None:
        index = (event.x - len(self.label) - 2) // SWATCH
        if 0 <= index < len(PALETTE):
            self.cursor = index
            self.action_pick()
