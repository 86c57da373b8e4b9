"""The daemon's ``sim`` camera source: frames rendered by the simulated world.

The world lives in the emulator's process (``darwin sim``); the daemon's camera thread calls
:meth:`SimCameraSource.read`, which asks the world for one frame through the simulator's
control queryable (op ``render``) on the daemon's own Zenoh session. A frame is rendered only
when asked for, so the camera thread's rule — capture only while someone subscribes — holds for
the renderer too. The world answers with a JPEG (encoded in the simulator's process), which the
camera thread forwards to viewers untouched, as it does a real camera's MJPEG: the daemon's path
is the same for both, and needs no OpenCV.

For the query to reach the world, the emulator must be on the daemon's Zenoh network: started
with ``--world-connect <daemon endpoint> --robot <name>`` (or ``--control-listen`` on an
endpoint the daemon connects to).
"""

from __future__ import annotations

from robot_daemon.vision.frames import JpegFrame
from robot_daemon.vision.sources import SourceContext, register_source
from schemas.sim_control import SimControl

# A frame request that takes longer than this means the world is gone (s).
RENDER_TIMEOUT = 2.0


class SimCameraSource:
    def __init__(self, ctx: SourceContext) -> None:
        if ctx.session is None:
            raise RuntimeError("the sim camera needs the daemon's Zenoh session")
        self.control = SimControl(ctx.session, ctx.robot, timeout=RENDER_TIMEOUT)
        self.quality = int(ctx.settings.get("daemon", {}).get("camera", {}).get("jpeg_quality", 80))

    def read(self) -> JpegFrame | None:
        reply = self.control.call("render", format="jpeg", quality=self.quality)
        w, h, data = int(reply["width"]), int(reply["height"]), reply.get("jpeg")
        if not isinstance(data, bytes) or not data.startswith(b"\xff\xd8"):
            raise RuntimeError(f"the world sent no JPEG frame for a {w}×{h} render")
        return JpegFrame(data, w, h)

    def close(self) -> None:
        pass


register_source("sim", SimCameraSource)
