"""A time-series plot drawn in braille: series toggled on and off, a zoomable time window."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

from rich.text import Text
from textual.widget import Widget

from clients.tui.i18n import _
from clients.tui.widgets.canvas import Canvas

WINDOWS_S: tuple[float, ...] = (2.0, 5.0, 10.0, 30.0)


@dataclass
class Series:
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

    def show(self, series: list[Series]) -> None:
        self._series = series
        self.refresh()

    def zoom(self, step: int) -> float:
        """Step the time window through ``WINDOWS_S`` (+1 wider, -1 narrower)."""
        i = WINDOWS_S.index(self.window_s) if self.window_s in WINDOWS_S else 1
        self.window_s = WINDOWS_S[max(0, min(len(WINDOWS_S) - 1, i + step))]
        self.refresh()
        return self.window_s

    def render(self) -> Text:
        width, height = self.content_size.width, self.content_size.height
        gutter = 8
        legend = Text(no_wrap=True, overflow="ellipsis")
        for s in self._series:
            mark = "■" if s.visible else "□"
            legend.append(f"{mark} {s.label}  ", style=s.colour if s.visible else "dim")
        legend.append(_("window {seconds:g} s").format(seconds=self.window_s), style="dim")
        if width <= gutter + 2 or height < 3:
            return legend
        canvas = Canvas(width - gutter, height - 1)
        shown = [s for s in self._series if s.visible and len(s.times)]
        if not shown:
            body = Text(_("no data"), style="dim")
            return Text("\n").join([legend, body])
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

        def xy(t: float, v: float) -> tuple[float, float]:
            x = (t - t_start) / self.window_s * (canvas.width - 1)
            y = (hi - v) / (hi - lo) * (canvas.height - 1)
            return x, y

        for s, pts in zip(shown, points, strict=True):
            for (t0, v0), (t1, v1) in itertools.pairwise(pts):
                canvas.line(*xy(t0, v0), *xy(t1, v1), s.colour)
            if len(pts) == 1:
                canvas.dot(*xy(*pts[0]), s.colour)
        lines = canvas.render().split("\n")
        rows = [legend]
        for r, line in enumerate(lines):
            if r == 0:
                label = f"{hi:>7.2f} "
            elif r == len(lines) - 1:
                label = f"{lo:>7.2f} "
            elif r == len(lines) // 2:
                label = f"{self.unit:>7} "
            else:
                label = " " * gutter
            rows.append(Text(label[:gutter], style="dim") + line)
        return Text("\n").join(rows)
