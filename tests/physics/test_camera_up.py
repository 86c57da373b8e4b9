"""``darwin up --physics mujoco --camera sim``: the daemon's camera frames come from MuJoCo's
offscreen camera in the emulator's process (its own GL thread, the world's ``render`` op over
Zenoh), and show the ball where it lies. The frame is written as a PNG under pytest's tmp dir
(``-s`` prints the path)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from config.loader import load_all
from robot_daemon.vision.ball_finder import BallFinder, FinderSettings
from tests.fixtures.system import start_system

mujoco = pytest.importorskip("mujoco")


def test_the_daemons_camera_shows_mujocos_view_of_the_ball(tmp_path: Path) -> None:
    # The world's start: robot at (-1, 0) facing +x, the ball at (-0.4, 0): 0.6 m ahead.
    with (
        start_system(camera="sim", gateway=False, extra_args=["--physics", "mujoco"]) as system,
        system.robot_client(name="camera-physics") as robot,
    ):
        rgb = robot.image(timeout=30.0)
        log = system.output()
    bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    path = tmp_path / "darwin-up-physics.png"
    assert cv2.imwrite(str(path), bgr)
    print(f"frame: {path}")
    if "draws with OpenCV" in log:
        pytest.skip("no OpenGL backend in the emulator: it drew with OpenCV")
    det = BallFinder(FinderSettings.from_config(load_all().get("ballplay", {}))).find(bgr)
    assert det.found, path
    assert abs(det.pan_error) < 0.15, det  # straight ahead
    # MuJoCo's field has no painted lines; the OpenCV renderer's centre circle is in this view.
    white = np.all(bgr > 200, axis=-1).mean()
    assert white < 0.002, f"{white:.4f} of the frame is white: field lines, so OpenCV drew it"
