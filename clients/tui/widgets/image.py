"""A camera image drawn with half-block characters: each cell shows two pixels (upper in the
foreground colour of ``▀``, lower in the background), which any true-colour terminal displays."""

from __future__ import annotations

import cv2
import numpy as np
from rich.color import Color
from rich.segment import Segment
from rich.style import Style
from textual.geometry import Size
from textual.strip import Strip
from textual.widget import Widget

from schemas.messages import BallDetection

UPPER_HALF = "▀"


def decode_jpeg(data: bytes) -> np.ndarray | None:
    """RGB pixels of a JPEG, or None when the bytes are not an image."""
    if not data:
        return None
    bgr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    return None if bgr is None else cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def fit(width: int, height: int, columns: int, rows: int) -> tuple[int, int]:
    """Cells ``(columns, rows)`` an image of ``width``×``height`` pixels fills, aspect kept
    (a cell holds two pixels one above the other, so it is about square per pixel)."""
    if width <= 0 or height <= 0 or columns <= 0 or rows <= 0:
        return 0, 0
    scale = min(columns / width, (rows * 2) / height)
    return max(1, int(width * scale)), max(1, int(height * scale / 2))


def overlay_ball(rgb: np.ndarray, ball: BallDetection | None) -> np.ndarray:
    """Draw the detected ball (a ring and a cross) on a copy of the image."""
    if ball is None or not ball.found:
        return rgb
    out = rgb.copy()
    h, w = out.shape[:2]
    sx, sy = w / max(1, ball.width), h / max(1, ball.height)
    cx, cy = int(ball.x * sx), int(ball.y * sy)
    radius = max(3, int((ball.size * w * h / np.pi) ** 0.5))
    cv2.circle(out, (cx, cy), radius, (255, 255, 0), max(1, w // 80))
    cv2.drawMarker(out, (cx, cy), (255, 255, 0), cv2.MARKER_CROSS, radius, max(1, w // 80))
    return out


class HalfBlockImage(Widget):
    DEFAULT_CSS = """
    HalfBlockImage { width: 1fr; height: 1fr; }
    """

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self._rgb: np.ndarray | None = None
        self._cells: np.ndarray | None = None
        self._size = Size(0, 0)

    def show(self, rgb: np.ndarray | None) -> None:
        self._rgb = rgb
        self._cells = None
        self.refresh()

    def _scaled(self) -> np.ndarray | None:
        size = self.content_size
        if self._rgb is None:
            return None
        if self._cells is None or size != self._size:
            h, w = self._rgb.shape[:2]
            cols, rows = fit(w, h, size.width, size.height)
            if cols == 0:
                return None
            self._cells = cv2.resize(self._rgb, (cols, rows * 2), interpolation=cv2.INTER_AREA)
            self._size = size
        return self._cells

    def render_line(self, y: int) -> Strip:
        cells = self._scaled()
        width = self.content_size.width
        if cells is None or y * 2 + 1 >= cells.shape[0]:
            return Strip.blank(width)
        top, bottom = cells[y * 2], cells[y * 2 + 1]
        pad = (width - cells.shape[1]) // 2
        segments = [Segment(" " * pad)] if pad > 0 else []
        for (r1, g1, b1), (r2, g2, b2) in zip(top.tolist(), bottom.tolist(), strict=True):
            style = Style(color=Color.from_rgb(r1, g1, b1), bgcolor=Color.from_rgb(r2, g2, b2))
            segments.append(Segment(UPPER_HALF, style))
        return Strip(segments).adjust_cell_length(width)
