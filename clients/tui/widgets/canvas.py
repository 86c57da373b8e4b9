"""A braille dot canvas: 2×4 dots per terminal cell, lines in colour, rendered as Rich text.

Pure (no widget): the plot and the stick figure draw on it, and unit tests can too.
"""

from __future__ import annotations

from collections.abc import Sequence

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
        # :meth:`dot` inlined: a live plot draws hundreds of thousands of these dots a second.
        steps = int(max(abs(x1 - x0), abs(y1 - y0))) + 1
        width, height, bits, colours = self.columns * 2, self.rows * 4, self._bits, self._colour
        dx, dy = x1 - x0, y1 - y0
        for i in range(steps + 1):
            t = i / steps
            xi, yi = round(x0 + dx * t), round(y0 + dy * t)
            if 0 <= xi < width and 0 <= yi < height:
                row, col = yi // 4, xi // 2
                bits[row][col] |= _DOTS[yi % 4][xi % 2]
                colours[row][col] = colour

    def polyline(self, points: Sequence[tuple[float, float]], colour: str) -> None:
        """The same dots as :meth:`line` between each pair of neighbours, for points in
        increasing x: where many points fall in one dot column (a 5 s window of a 125 Hz
        stream on a few hundred columns) their segments there fill exactly the column's run
        between its lowest and highest point, so that run is drawn once and only the segment
        into the next column is traced."""
        column: int | None = None
        lo = hi = 0
        last: tuple[float, float] | None = None
        for point in points:
            x, y = point
            c, r = round(x), round(y)
            if c == column:
                lo, hi = min(lo, r), max(hi, r)
            else:
                if column is not None and last is not None:
                    self._run(column, lo, hi, colour)
                    self.line(*last, x, y, colour)
                column, lo, hi = c, r, r
            last = point
        if column is not None:
            self._run(column, lo, hi, colour)

    def _run(self, x: int, y0: int, y1: int, colour: str) -> None:
        if not 0 <= x < self.width:
            return
        col, bit_column = x // 2, x % 2
        for y in range(max(0, y0), min(self.height - 1, y1) + 1):
            row = y // 4
            self._bits[row][col] |= _DOTS[y % 4][bit_column]
            self._colour[row][col] = colour

    def text(self, column: int, row: int, value: str, colour: str = "default") -> None:
        """Write plain characters over the dots (labels, markers)."""
        for i, ch in enumerate(value):
            if 0 <= column + i < self.columns and 0 <= row < self.rows:
                self._text[(row, column + i)] = (ch, colour)

    def runs(self, row: int) -> list[tuple[str, str | None]]:
        """Row ``row`` as runs of characters in one colour (None: blank cells), left to right."""
        out: list[tuple[str, str | None]] = []
        run: list[str] = []
        run_colour: str | None = None
        bits_row, colour_row, text = self._bits[row], self._colour[row], self._text
        for c in range(self.columns):
            label = text.get((row, c)) if text else None
            if label is not None:
                ch, colour = label
            elif bits_row[c]:
                ch, colour = chr(_BRAILLE + bits_row[c]), colour_row[c] or "default"
            else:
                ch, colour = " ", None
            if colour != run_colour and run:
                out.append(("".join(run), run_colour))
                run = []
            run_colour = colour
            run.append(ch)
        if run:
            out.append(("".join(run), run_colour))
        return out

    def render(self) -> Text:
        # One span per run of cells in the same colour, not one per cell (a plot redrawn 15
        # times a second would hand Textual a styled span for every character).
        out = Text(no_wrap=True, overflow="crop")
        for r in range(self.rows):
            for chars, colour in self.runs(r):
                out.append(chars, Style.parse(colour) if colour else None)
            if r < self.rows - 1:
                out.append("\n")
        return out
