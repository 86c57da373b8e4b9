"""Log: the robot's events as they come, and recording the session to a file (MCAP, or the
original's plain text for ``.txt``/``.log``) with :class:`clients.recording.Recorder`, in one
file or in segments (the split field: ``60s``, ``10m``, ``50MB``, ``10m 1GB``), as the project's
channels or, with "ROS 2 bag" ticked, as a ROS 2 bag (``darwin record --ros2``)."""

from __future__ import annotations

import time
from dataclasses import dataclass

from rich.text import Text
from textual import events
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.geometry import Size
from textual.message import Message
from textual.widgets import Button, Checkbox, Input, RichLog, Static

from clients.tui.i18n import N_, _
from clients.tui.model import Model
from clients.tui.tabs.base import TabView
from schemas.messages import Event

LEVELS = {"fault": "bold red", "servo_alarm": "red", "fall": "bold red", "lease": "cyan"}


def event_line(event: Event) -> Text:
    # UTC with a Z: the same on every machine of a fleet, and what the recordings carry.
    clock = time.strftime("%H:%M:%S", time.gmtime(event.stamp))
    line = Text(no_wrap=False)
    line.append(f"{clock}Z ", style="dim")
    line.append(f"{event.kind:<14} ", style=LEVELS.get(event.kind, "green"))
    line.append(event.message)
    return line


class EventsLog(RichLog):
    """A RichLog that renders what it holds once the layout gives it a width.

    RichLog holds every write until its first Resize event says how wide it is. In tmux on a
    loaded machine, after F2 had composed the screen again, the Log tab's log was laid out
    (78x16) without that event ever being handled (1 run in 12 with two busy loops): every
    event stayed held, and the Events panel stayed empty for the rest of the session. So the
    width is taken from the layout as well, on the app's next turn, if no Resize came first."""

    def _size_updated(
        self, size: Size, virtual_size: Size, container_size: Size, layout: bool = True
    ) -> bool:
        resized = super()._size_updated(size, virtual_size, container_size, layout)
        if size.width and not self._size_known:
            # On the app's queue, not this widget's: a Resize lost on the way to this widget
            # must not be needed for it.
            self.app.call_later(self._take_width)
        return resized

    def _take_width(self) -> None:
        if self.size.width and not self._size_known:
            self.on_resize(events.Resize(self.size, self.virtual_size, self.container_size))


class LogTab(TabView):
    TAB_ID = "log"
    WATCHES = ("events",)
    DEFAULT_CSS = """
    LogTab RichLog { height: 1fr; border: round $primary-darken-2; }
    LogTab #record-path { width: 1fr; }
    LogTab #record-split { width: 14; margin-left: 1; }
    LogTab #record-ros2 { width: auto; margin-left: 1; }
    LogTab Button { min-width: 0; margin-left: 1; }
    LogTab #record-state { width: auto; margin-left: 1; }
    """
    BINDINGS = [Binding("r", "record", N_("Record on/off"))]

    @dataclass
    class Record(Message):
        """Start recording to ``path`` (in segments of ``split_seconds`` / ``split_bytes`` when
        given, with the recorder's ``profile``), or stop when ``path`` is None."""

        path: str | None
        split_seconds: float | None = None
        split_bytes: int | None = None
        tab: LogTab | None = None
        profile: str = "darwin"

        @property
        def control(self) -> LogTab | None:
            # The app answers with set_recording() on the tab that asked.
            return self.tab

    def __init__(self, model: Model) -> None:
        super().__init__(model)
        self._shown = 0
        self.recording = False

    def compose(self) -> ComposeResult:
        with Horizontal(classes="bar"):
            yield self.stream_box()
            yield Input("session.mcap", id="record-path", compact=True)
            yield Input(placeholder=_("split: 10m 1GB"), id="record-split", compact=True)
            yield Checkbox(_("ROS 2 bag"), id="record-ros2", compact=True)
            yield Button(_("Record"), id="record-button", compact=True)
            yield Static("", id="record-state")
        yield EventsLog(id="events", wrap=True, markup=False, max_lines=2000)

    def on_mount(self) -> None:
        self.query_one(RichLog).border_title = _("Events")
        self.refresh_view(self.model)
        # A recording started from this tab before F2 composed the screen again: shown as
        # running, so that `r` stops it rather than start a second one beside it.
        where = getattr(self.app, "recording_to", None)
        if where is not None:
            self.set_recording(True, _("recording to {path}").format(path=where))

    def refresh_view(self, model: Model) -> None:
        log = self.query_one(RichLog)
        # The model keeps the last EVENTS; write only those not yet shown.
        new = min(model.event_count - self._shown, len(model.events))
        for event in list(model.events)[len(model.events) - new :] if new > 0 else []:
            log.write(event_line(event))
        self._shown = model.event_count

    def set_recording(self, on: bool, detail: str) -> None:
        self.recording = on
        self.query_one("#record-button", Button).label = _("Stop") if on else _("Record")
        self.query_one("#record-state", Static).update(
            Text(detail, style="bold red" if on else "dim")
        )

    def action_record(self) -> None:
        path = self.query_one("#record-path", Input).value.strip()
        if self.recording:
            self.post_message(self.Record(None, tab=self))
            return
        if not path:
            self.notify_error(_("Type the file to record to, e.g. session.mcap"))
            return
        from clients.recording.segments import parse_split

        try:
            seconds, size = parse_split(self.query_one("#record-split", Input).value)
        except ValueError as exc:
            self.notify_error(str(exc))
            return
        profile = "ros2" if self.query_one("#record-ros2", Checkbox).value else "darwin"
        self.post_message(self.Record(path, seconds, size, tab=self, profile=profile))

    def on_button_pressed(self, event: Button.Pressed) -> None:
        self.action_record()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        if not self.recording:
            self.action_record()
