"""Camera: the live image in half-block characters, frame rate, the ball detection overlay.
The app subscribes to the camera only while this tab shows with its stream on (the daemon
captures only while someone watches)."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.message import Message
from textual.widgets import Checkbox, Static

from clients.tui.i18n import _
from clients.tui.model import Model
from clients.tui.tabs.base import TabView
from clients.tui.widgets.image import HalfBlockImage, decode_jpeg, overlay_ball


class CameraTab(TabView):
    TAB_ID = "camera"
    WATCHES = ("camera",)
    DEFAULT_CSS = """
    CameraTab #camera-info { width: 1fr; }
    """

    class Wanted(Message):
        """The camera stream was switched on or off."""

    def compose(self) -> ComposeResult:
        with Horizontal(classes="bar"):
            yield self.stream_box()
            yield Static("", id="camera-info")
        yield HalfBlockImage(id="camera-image")

    def on_mount(self) -> None:
        self.refresh_view(self.model)

    def on_checkbox_changed(self, event: Checkbox.Changed) -> None:
        self.post_message(self.Wanted())

    def refresh_view(self, model: Model) -> None:
        frame, ball = model.frame, model.ball
        info = self.query_one("#camera-info", Static)
        image = self.query_one(HalfBlockImage)
        if frame is None:
            info.update(_("no image yet (is a camera configured on the robot?)"))
            image.show(None)
            return
        rgb = decode_jpeg(frame.jpeg)
        if rgb is None:
            info.update(_("frame {seq}: not a JPEG image").format(seq=frame.seq))
            return
        text = _("{w}×{h}, {fps:.1f} fps, frame {seq}").format(
            w=frame.width, h=frame.height, fps=model.fps(), seq=frame.seq
        )
        if ball is not None and (ball.found or ball.phase):
            seen = _("ball at ({x:.0f}, {y:.0f})").format(x=ball.x, y=ball.y)
            text += " · " + (seen if ball.found else _("no ball"))
            if ball.phase:
                text += " · " + _("play ball: {phase}").format(phase=ball.phase)
        info.update(text)
        image.show(overlay_ball(rgb, ball))
