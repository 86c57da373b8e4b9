"""The simulated camera end to end: the world (in the emulator's process) sends the JPEG a UVC
camera in MJPEG would, and the daemon forwards those bytes to viewers untouched — no decoding,
no re-encoding — with the same message and fields as before."""

from __future__ import annotations

import cv2
import numpy as np

from schemas.messages import CameraFrame
from schemas.sim_control import SimControl


def test_viewers_get_the_worlds_jpeg_passed_through(system_factory) -> None:
    system = system_factory(camera="sim")
    with system.robot_client(name="viewer") as robot:
        robot.wait_for("status", lambda s: s.camera.get("subscribed") is False, 30.0, fresh=False)
        frames = robot.collect("camera", 30.0, max_messages=5)
        assert len(frames) == 5
        for f in frames:
            assert isinstance(f, CameraFrame)
            assert f.jpeg.startswith(b"\xff\xd8") and (f.width, f.height) == (320, 240)
        assert [f.seq for f in frames] == sorted(f.seq for f in frames)
        # Every frame viewers got was the world's own JPEG, forwarded as it came. (The two
        # counts are read apart: a status taken during a put may be one apart; the next agrees.)
        robot.wait_for(
            "status",
            lambda s: s.camera.get("published", 0) >= 5
            and s.camera["passed_through"] == s.camera["published"],
            30.0,
            fresh=True,
        )
        # The same picture as the world renders (the robot stands still: the scene is static).
        raw = SimControl(robot.session, system.robot).call("render")
        world = np.frombuffer(raw["bgr"], np.uint8).reshape(raw["height"], raw["width"], 3)
        seen = cv2.imdecode(np.frombuffer(frames[-1].jpeg, np.uint8), cv2.IMREAD_COLOR)
        diff = np.abs(seen.astype(int) - world.astype(int)).mean()
        print(f"\nmean difference viewer frame vs world render: {diff:.2f} / 255")
        assert diff < 10.0  # JPEG loss only, not another picture
