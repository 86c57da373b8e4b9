"""The braille canvas renders each cell as drawn, in as few styled runs as its colours allow."""

from __future__ import annotations

import itertools
import random

from rich.cells import cell_len
from rich.console import Console
from rich.style import Style

from clients.tui.widgets.canvas import Canvas
from clients.tui.widgets.plot import _ellipsis


def _expected(canvas: Canvas, row: int, column: int) -> tuple[str, str | None]:
    label = canvas._text.get((row, column))
    if label is not None:
        return label
    bits = canvas._bits[row][column]
    if bits:
        return chr(0x2800 + bits), canvas._colour[row][column] or "default"
    return " ", None


def test_every_cell_keeps_its_character_and_colour_in_one_span_per_run() -> None:
    rng = random.Random(7)
    console = Console()
    colours = ["yellow", "cyan", "red", "default"]
    for _ in range(30):
        canvas = Canvas(rng.randint(1, 40), rng.randint(1, 8))
        for _ in range(rng.randint(0, 12)):
            canvas.line(
                rng.uniform(-5, canvas.width + 5), rng.uniform(-5, canvas.height + 5),
                rng.uniform(-5, canvas.width + 5), rng.uniform(-5, canvas.height + 5),
                rng.choice(colours),
            )  # fmt: skip
        for _ in range(rng.randint(0, 3)):
            canvas.text(rng.randrange(canvas.columns), rng.randrange(canvas.rows), "ab", "red")
        text = canvas.render()
        lines = text.split("\n")
        assert len(lines) == canvas.rows
        runs = 0
        for r, line in enumerate(lines):
            assert len(line.plain) == canvas.columns
            previous: str | object | None = object()
            for c in range(canvas.columns):
                ch, colour = _expected(canvas, r, c)
                assert line.plain[c] == ch
                style = line.get_style_at_offset(console, c)
                assert style == (Style.parse(colour) if colour else Style.null())
                if colour != previous and colour is not None:
                    runs += 1
                previous = colour
        styled = [s for s in text.spans if s.style]
        assert len(styled) <= runs  # one span per run of a colour, never one per cell


def test_a_polyline_draws_the_dots_of_every_segment_between_its_points() -> None:
    rng = random.Random(11)
    for case in range(200):
        columns, rows = rng.randint(1, 60), rng.randint(1, 10)
        by_segments, by_polyline = Canvas(columns, rows), Canvas(columns, rows)
        n = rng.choice([0, 1, 2, 5, 50, 600])
        x = rng.uniform(-10, 5)
        points = []
        for _ in range(n):  # dense, noisy and partly off the canvas, as a live stream is
            x += rng.choice([0.0, rng.uniform(0, 0.6), rng.uniform(0, 3), -0.4 * (case % 7 == 0)])
            points.append((x, rng.gauss(by_segments.height / 2, by_segments.height)))
        for a, b in itertools.pairwise(points):
            by_segments.line(*a, *b, "cyan")
        if len(points) == 1:
            by_segments.dot(*points[0], "cyan")
        by_polyline.polyline(points, "cyan")
        assert by_polyline._bits == by_segments._bits, case
        assert by_polyline._colour == by_segments._colour, case


def test_a_plot_legend_too_long_for_its_width_ends_in_an_ellipsis() -> None:
    runs: list[tuple[str, str | None]] = [
        ("■ x  ", "red"),
        ("■ y  ", "green"),
        ("window 5 s", "dim"),
    ]
    assert _ellipsis(runs, 40) == runs  # it fits: unchanged
    for width in range(1, 20):
        cut = _ellipsis(runs, width)
        assert sum(cell_len(text) for text, _name in cut) == width
        assert cut[-1][0] == "…"
        assert "".join(t for t, _n in cut)[:-1] == "■ x  ■ y  window 5 s"[: width - 1]
