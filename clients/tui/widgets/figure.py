"""The robot as a stick figure, front and side, from forward kinematics of joint angles."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from rich.text import Text
from textual.widget import Widget

from clients.tui.i18n import _
from clients.tui.widgets.canvas import Canvas
from schemas.kinematics import SKELETON_BONES, skeleton

# Body-frame extent drawn (m): arms hanging or half raised, feet to the top of the head
# (arms stretched sideways leave the view a little: a bigger figure is worth more).
HALF_SPAN = 0.2
Z_TOP, Z_BOTTOM = 0.17, -0.33


def _colour(a: str, b: str) -> str:
    side = {a[:2], b[:2]}
    if "r_" in side:
        return "red1"
    if "l_" in side:
        return "dodger_blue1"
    return "bright_white"


def draw(positions: Mapping[int, float], columns: int, rows: int) -> Text:
    """Front view (robot facing you: its left on your right) and side view (facing right)."""
    canvas = Canvas(columns, rows)
    points = skeleton(dict(positions))
    half = canvas.width // 2
    # Braille dots are about square, so one scale for both axes keeps the figure's proportions.
    scale = min((half - 4) / (2 * HALF_SPAN), (canvas.height - 5) / (Z_TOP - Z_BOTTOM))

    def front(p: np.ndarray) -> tuple[float, float]:
        _x, y, z = p
        return half / 2 + y * scale, 4 + (Z_TOP - z) * scale

    def side(p: np.ndarray) -> tuple[float, float]:
        x, _y, z = p
        return half + half / 2 + x * scale, 4 + (Z_TOP - z) * scale

    for a, b in SKELETON_BONES:
        colour = _colour(a, b)
        canvas.line(*front(points[a]), *front(points[b]), colour)
        canvas.line(*side(points[a]), *side(points[b]), colour)
    ground = 4 + (Z_TOP - Z_BOTTOM) * scale
    canvas.line(2, ground, canvas.width - 3, ground, "grey37")
    canvas.text(1, 0, _("front"), "dim")
    canvas.text(columns // 2 + 1, 0, _("side"), "dim")
    return canvas.render()


class StickFigure(Widget):
    DEFAULT_CSS = """
    StickFigure { width: 1fr; height: 1fr; min-height: 8; border: round $primary-darken-2; }
    """

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self._positions: dict[int, float] = {}

    def show(self, positions: Mapping[int, float], title: str) -> None:
        positions = dict(positions)
        if positions == self._positions and title == self.border_title:
            return  # the same figure: drawing it again 15 times a second would cost for nothing
        self._positions = positions
        self.border_title = title
        self.refresh()

    def render(self) -> Text:
        size = self.content_size
        if size.width < 4 or size.height < 3:
            return Text("")
        return draw(self._positions, size.width, size.height)
