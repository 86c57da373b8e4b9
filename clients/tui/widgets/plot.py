"""A time-series plot drawn in braille: series toggled on and off, a zoomable time window."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from rich.cells import cell_len, set_cell_size
from rich.segment import Segment
from rich.style import Style
from textual.geometry import Size
from textual.strip import Strip
from textual.widget import Widget

from clients.tui.i18n import _
from clients.tui.widgets.canvas import Canvas

WINDOWS_S: tuple[float, ...] = (2.0, 5.0, 10.0, 30.0)


@dataclass
class Series:
    """One line of a plot: its label, colour and samples."""

    label: str
    colour: str
    times: Sequence[float]
    values: Sequence[float]
    visible: bool = True


class Plot(Widget):
    """Call :meth:`show` with the series; it redraws at the next refresh."""

    DEFAULT_CSS = """
    Plot { height: 1fr; min-height: 5; border: round $primary-darken-2; }
    """

    def __init__(self, title: str, unit: str, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.border_title = title
        self.unit = unit
        self.window_s = WINDOWS_S[1]
        self._series: list[Series] = []
        self._strips: list[Strip] | None = None  # drawn at the first line asked for
        self._drawn_for: tuple[Size, Style] | None = None

    def show(self, series: list[Series]) -> None:
        self._series = series
        self._strips = None
        self.refresh()

    def zoom(self, step: int) -> float:
        """Step the time window through ``WINDOWS_S`` (+1 wider, -1 narrower)."""
        i = WINDOWS_S.index(self.window_s) if self.window_s in WINDOWS_S else 1
        self.window_s = WINDOWS_S[max(0, min(len(WINDOWS_S) - 1, i + step))]
        self._strips = None
        self.refresh()
        return self.window_s

    def render_line(self, y: int) -> Strip:
        # Textual's line API: the plot draws its rows as strips of styled runs itself. Handing
        # Textual a Rich Text to lay out instead cost more than the drawing, 15 times a second
        # for each plot on the screen (most of a live tab's CPU).
        size, base = self.content_size, self.visual_style.rich_style
        if self._strips is None or self._drawn_for != (size, base):
            self._strips = self._draw(size.width, size.height, base)
            self._drawn_for = (size, base)
        if 0 <= y < len(self._strips):
            return self._strips[y]
        return Strip.blank(size.width, base)

    def _draw(self, width: int, height: int, base: Style) -> list[Strip]:
        styles: dict[str | None, Style] = {}

        def style(name: str | None) -> Style:
            if name not in styles:
                styles[name] = base + Style.parse(name) if name else base
            return styles[name]

        def strip(runs: list[tuple[str, str | None]]) -> Strip:
            return Strip([Segment(text, style(name)) for text, name in runs if text])

        gutter = 8
        legend: list[tuple[str, str | None]] = [
            (f"{'■' if s.visible else '□'} {s.label}  ", s.colour if s.visible else "dim")
            for s in self._series
        ]
        legend.append((_("window {seconds:g} s").format(seconds=self.window_s), "dim"))
        top = strip(_ellipsis(legend, width))
        if width <= gutter + 2 or height < 3:
            return [top]
        canvas = Canvas(width - gutter, height - 1)
        shown = [s for s in self._series if s.visible and len(s.times)]
        if not shown:
            return [top, strip([(_("no data"), "dim")]).crop(0, width)]
        t_end = max(s.times[-1] for s in shown)
        t_start = t_end - self.window_s
        points = [
            [(t, v) for t, v in zip(s.times, s.values, strict=False) if t >= t_start] for s in shown
        ]
        values = [v for pts in points for _t, v in pts]
        lo, hi = (min(values), max(values)) if values else (0.0, 1.0)
        if hi - lo < 1e-6:
            lo, hi = lo - 0.5, hi + 0.5
        pad = (hi - lo) * 0.05
        lo, hi = lo - pad, hi + pad
        window, span, x_dots, y_dots = self.window_s, hi - lo, canvas.width - 1, canvas.height - 1
        for s, pts in zip(shown, points, strict=True):
            xy = [((t - t_start) / window * x_dots, (hi - v) / span * y_dots) for t, v in pts]
            canvas.polyline(xy, s.colour)
        rows = [top]
        for r in range(canvas.rows):
            if r == 0:
                label = f"{hi:>7.2f} "
            elif r == canvas.rows - 1:
                label = f"{lo:>7.2f} "
            elif r == canvas.rows // 2:
                label = f"{self.unit:>7} "
            else:
                label = " " * gutter
            rows.append(strip([(label[:gutter], "dim"), *canvas.runs(r)]))
        return rows


def _ellipsis(runs: list[tuple[str, str | None]], width: int) -> list[tuple[str, str | None]]:
    """``runs`` cut to ``width`` cells with "…" at the end when they are longer (one line)."""
    if sum(cell_len(text) for text, _name in runs) <= width:
        return runs
    out: list[tuple[str, str | None]] = []
    room = max(0, width - 1)
    for text, name in runs:
        if room <= 0:
            break
        piece = set_cell_size(text, room) if cell_len(text) > room else text
        out.append((piece, name))
        room -= cell_len(piece)
    last_name = out[-1][1] if out else None
    out.append(("…", last_name))
    return out
