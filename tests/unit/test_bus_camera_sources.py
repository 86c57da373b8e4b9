"""Camera sources: the test pattern, the registry, and clear errors for unknown cameras."""

from __future__ import annotations

import numpy as np
import pytest

from robot_daemon.vision import sources
from robot_daemon.vision.sources import CameraError, SourceContext, open_source, register_source


def test_pattern_frames_have_the_asked_size_and_move() -> None:
    src = open_source("pattern", SourceContext(width=160, height=120))
    assert src is not None
    a, b = src.read(), src.read()
    assert a.shape == (120, 160, 3) and a.dtype == np.uint8
    assert not np.array_equal(a, b)  # the frame counter (and the ball) move
    src.close()


def test_none_opens_nothing_and_unknown_names_list_the_choices() -> None:
    assert open_source("none", SourceContext()) is None
    with pytest.raises(CameraError, match="pattern"):
        open_source("kinect", SourceContext())


def test_registered_sources_win(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sources, "_SOURCES", dict(sources._SOURCES))

    class Black:
        def __init__(self, ctx: SourceContext) -> None:
            self.shape = (ctx.height, ctx.width, 3)

        def read(self) -> np.ndarray:
            return np.zeros(self.shape, dtype=np.uint8)

        def close(self) -> None:
            pass

    register_source("black", Black)
    src = open_source("black", SourceContext(width=8, height=4))
    assert src is not None and src.read().shape == (4, 8, 3)
    assert "black" in sources.source_names()
