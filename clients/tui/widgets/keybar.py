"""The footer: the keys that work here, with their descriptions translated at render time
(Textual's own Footer would show the English text the bindings were declared with)."""

from __future__ import annotations

from rich.text import Text
from textual.widget import Widget

from clients.tui.i18n import _


class KeyBar(Widget):
    DEFAULT_CSS = """
    KeyBar { dock: bottom; height: 1; background: $panel; }
    """

    def on_mount(self) -> None:
        self.watch(self.screen, "focused", self._focus_moved, init=False)
        self.set_interval(0.5, self.refresh)  # tab switches change the active bindings too

    def _focus_moved(self, _focused: Widget | None) -> None:
        self.refresh()

    def render(self) -> Text:
        out = Text(no_wrap=True, overflow="ellipsis")
        seen: set[str] = set()
        for active in self.screen.active_bindings.values():
            binding = active.binding
            if not binding.show or not binding.description:
                continue
            if binding.description in seen:
                continue
            seen.add(binding.description)
            label = binding.key_display or self.app.get_key_display(binding)
            if active.enabled:
                out.append(f" {label} ", style="bold reverse")
                out.append(f" {_(binding.description)} ")
            else:  # greyed: this connection's role may not (schemas.roles)
                out.append(f" {label} ", style="dim reverse")
                out.append(f" {_(binding.description)} ", style="dim strike")
        return out
