"""Live views for Jupyter that never block the kernel: a plot of chosen signals and the camera.

    >>> plot = LivePlot(robot, ["imu.gyro_x", "imu.gyro_y", "joints.position_r_knee"])
    >>> plot                 # shows the widget; it updates on its own until plot.stop()
    >>> cam = LiveCamera(robot); cam

Zenoh callbacks only append to bounded buffers; one daemon thread per view renders at most every
``interval`` seconds into an ``ipywidgets.Image`` (matplotlib's Agg canvas for plots, the JPEG
bytes as they arrive for the camera), so the notebook stays responsive and a fast topic cannot
back up the browser. The camera is subscribed only while a ``LiveCamera`` runs.
"""

from __future__ import annotations

import functools
import io
import threading
from collections import deque
from typing import Any, Self

import ipywidgets as widgets
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from clients.dataframes import row
from clients.robot import TOPICS, Robot, Subscription
from schemas.messages import CameraFrame, Message


def parse_signal(signal: str) -> tuple[str, str]:
    """``"imu.gyro_x"`` → (``"imu"``, ``"gyro_x"``); the column names are those of
    :func:`clients.dataframes.row`."""
    topic, sep, column = signal.partition(".")
    if not sep or topic not in TOPICS or not column:
        raise ValueError(
            f"signal {signal!r} should be <topic>.<column>, e.g. imu.gyro_x or "
            f"joints.position_r_knee; topics: {', '.join(TOPICS)}"
        )
    return topic, column


class _View:
    """A background renderer: ``start()`` subscribes and starts the thread, ``stop()`` ends
    both. Shown in a notebook as its widget."""

    widget: widgets.Image

    def __init__(self, interval: float) -> None:
        self.interval = interval
        self.frames = 0  # renders so far (what tests and curious users look at)
        self._stop = threading.Event()
        self._drawn = threading.Condition()
        self._thread: threading.Thread | None = None
        self._subs: list[Subscription] = []

    def _subscribe(self) -> None:
        raise NotImplementedError

    def _render(self) -> bytes | None:
        raise NotImplementedError

    def start(self) -> Self:
        if self._thread is not None:
            return self
        self._subscribe()
        self._thread = threading.Thread(target=self._run, name=type(self).__name__, daemon=True)
        self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.wait(self.interval):
            image = self._render()
            if image is not None:
                self.widget.value = image
                with self._drawn:
                    self.frames += 1
                    self._drawn.notify_all()

    def wait(self, frames: int = 1, timeout: float = 10.0) -> bool:
        """Block until ``frames`` pictures have been drawn in all; False after ``timeout``."""
        with self._drawn:
            return self._drawn.wait_for(lambda: self.frames >= frames, timeout)

    def stop(self) -> None:
        self._stop.set()
        for sub in self._subs:
            sub.close()
        self._subs.clear()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _repr_mimebundle_(self, **kwargs: Any) -> Any:
        return self.widget._repr_mimebundle_(**kwargs)


class LivePlot(_View):
    """Signals (``"<topic>.<column>"``) over the last ``window`` seconds, redrawn every
    ``interval`` seconds."""

    def __init__(
        self,
        robot: Robot,
        signals: list[str],
        window: float = 10.0,
        interval: float = 0.25,
        size: tuple[float, float] = (8.0, 3.0),
        start: bool = True,
    ) -> None:
        super().__init__(interval)
        if not signals:
            raise ValueError("give at least one signal, e.g. ['imu.gyro_x']")
        self.robot = robot
        self.signals = [parse_signal(s) for s in signals]
        self.window = window
        self._buffers: dict[tuple[str, str], deque[tuple[float, float]]] = {
            s: deque(maxlen=20_000) for s in self.signals
        }
        self._fig = Figure(figsize=size, dpi=80)
        self._canvas = FigureCanvasAgg(self._fig)
        self._ax = self._fig.add_subplot()
        self.widget = widgets.Image(format="png")
        if start:
            self.start()

    def __repr__(self) -> str:
        names = ", ".join(f"{t}.{c}" for t, c in self.signals)
        return f"<LivePlot {names}: {self.frames} frames>"

    def _subscribe(self) -> None:
        for topic in dict.fromkeys(t for t, _ in self.signals):
            columns = [c for t, c in self.signals if t == topic]
            self._subs.append(
                self.robot.subscribe(topic, functools.partial(self._on, topic, columns))
            )

    def _on(self, topic: str, columns: list[str], msg: Message) -> None:
        values = row(msg)
        stamp = float(values.get("stamp", 0.0))
        for c in columns:
            v = values.get(c)
            if isinstance(v, int | float):
                self._buffers[(topic, c)].append((stamp, float(v)))

    def data(self) -> dict[str, list[tuple[float, float]]]:
        """The buffered (stamp, value) pairs per signal."""
        return {f"{t}.{c}": list(buf) for (t, c), buf in self._buffers.items()}

    def _render(self) -> bytes | None:
        series = {k: list(v) for k, v in self._buffers.items()}
        latest = max((pts[-1][0] for pts in series.values() if pts), default=None)
        if latest is None:
            return None
        ax = self._ax
        ax.clear()
        for (topic, column), pts in series.items():
            pts = [(s - latest, v) for s, v in pts if s >= latest - self.window]
            if pts:
                xs, ys = zip(*pts, strict=True)
                ax.plot(xs, ys, label=f"{topic}.{column}")
        ax.set_xlim(-self.window, 0.0)
        ax.set_xlabel("seconds (0 = now)")
        ax.legend(loc="upper left", fontsize="small")
        ax.grid(True, alpha=0.3)
        buf = io.BytesIO()
        self._canvas.print_png(buf)
        return buf.getvalue()


class LiveCamera(_View):
    """The robot's camera, at most one new picture every ``interval`` seconds."""

    def __init__(self, robot: Robot, interval: float = 0.1, start: bool = True) -> None:
        super().__init__(interval)
        self.robot = robot
        self._latest: CameraFrame | None = None
        self._shown = -1
        self.widget = widgets.Image(format="jpeg")
        if start:
            self.start()

    def __repr__(self) -> str:
        return f"<LiveCamera {self.robot.target.robot}: {self.frames} frames>"

    def _subscribe(self) -> None:
        self._subs.append(self.robot.subscribe("camera", self._on))

    def _on(self, msg: Message) -> None:
        if isinstance(msg, CameraFrame):
            self._latest = msg

    def _render(self) -> bytes | None:
        frame = self._latest
        if frame is None or frame.seq == self._shown:
            return None
        self._shown = frame.seq
        return bytes(frame.jpeg)
