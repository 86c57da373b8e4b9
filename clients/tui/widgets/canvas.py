"""A braille dot canvas: 2×4 dots per terminal cell, lines in colour, rendered as Rich text.

Pure (no widget): the plot and the stick figure draw on it, and unit tests can too.
"""

from __future__ import annotations

from rich.style import Style
from rich.text import Text

# Bit of each dot inside a braille cell, indexed [row][column].
_DOTS = ((0x01, 0x08), (0x02, 0x10), (0x04, 0x20), (0x40, 0x80))
_BRAILLE = 0x2800


class Canvas:
    def __init__(self, columns: int, rows: int) -> None:
        self.columns = max(1, columns)
        self.rows = max(1, rows)
        self._bits = [[0] * self.columns for _ in range(self.rows)]
        self._colour: list[list[str | None]] = [[None] * self.columns for _ in range(self.rows)]
        self._text: dict[tuple[int, int], tuple[str, str]] = {}

    @property
    def width(self) -> int:
        """Width in dots."""
        return self.columns * 2

    @property
    def height(self) -> int:
        """Height in dots."""
        return self.rows * 4

    def dot(self, x: float, y: float, colour: str) -> None:
        xi, yi = round(x), round(y)
        if 0 <= xi < self.width and 0 <= yi < self.height:
            row, col = yi // 4, xi // 2
            self._bits[row][col] |= _DOTS[yi % 4][xi % 2]
            self._colour[row][col] = colour

    def line(self, x0: float, y0: float, x1: float, y1: float, colour: str) -> None:
        steps = int(max(abs(x1 - x0), abs(y1 - y0))) + 1
        for i in range(steps + 1):
            t = i / steps
            self.dot(x0 + (x1 - x0) * t, y0 + (y1 - y0) * t, colour)

    def text(self, column: int, row: int, value: str, colour: str = "default") -> None:
        """Write plain characters over the dots (labels, markers)."""
        for i, ch in enumerate(value):
            if 0 <= column + i < self.columns and 0 <= row < self.rows:
                self._text[(row, column + i)] = (ch, colour)

    def render(self) -> Text:
        out = Text(no_wrap=True, overflow="crop")
        for r in range(self.rows):
            for c in range(self.columns):
                label = self._text.get((r, c))
                if label is not None:
                    out.append(label[0], Style.parse(label[1]))
                    continue
                bits = self._bits[r][c]
                if bits:
                    out.append(chr(_BRAILLE + bits), Style.parse(self._colour[r][c] or "default"))
                else:
                    out.append(" ")
            if r < self.rows - 1:
                out.append("\n")
        return out
