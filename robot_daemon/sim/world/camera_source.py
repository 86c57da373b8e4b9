"""The daemon's ``sim`` camera source: frames rendered by the simulated world.

The world lives in the emulator's process (``darwin sim``); the daemon's camera thread calls
:meth:`SimCameraSource.read`, which asks the world for one frame through the simulator's
control queryable (op ``render``) on the daemon's own Zenoh session. A frame is rendered only
when asked for, so the camera thread's rule — capture only while someone subscribes — holds for
the renderer too.

For the query to reach the world, the emulator must be on the daemon's Zenoh network: started
with ``--world-connect <daemon endpoint> --robot <name>`` (or ``--control-listen`` on an
endpoint the daemon connects to).
"""

from __future__ import annotations

import numpy as np

from robot_daemon.sim.control import SimControl
from robot_daemon.vision.sources import SourceContext, register_source

# A frame request that takes longer than this means the world is gone (s).
RENDER_TIMEOUT = 2.0


class SimCameraSource:
    def __init__(self, ctx: SourceContext) -> None:
        if ctx.session is None:
            raise RuntimeError("the sim camera needs the daemon's Zenoh session")
        self.control = SimControl(ctx.session, ctx.robot, timeout=RENDER_TIMEOUT)

    def read(self) -> np.ndarray | None:
        reply = self.control.call("render")
        w, h = int(reply["width"]), int(reply["height"])
        data = reply["bgr"]
        if len(data) != w * h * 3:
            raise RuntimeError(f"the world sent {len(data)} bytes for a {w}×{h} BGR frame")
        return np.frombuffer(data, dtype=np.uint8).reshape(h, w, 3)

    def close(self) -> None:
        pass


register_source("sim", SimCameraSource)
