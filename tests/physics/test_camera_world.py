"""The physics world's camera: MuJoCo draws the head camera's view, the daemon's ball finder
sees the ball in it where the OpenCV renderer (at the same camera pose) puts it, and without GL
the world draws with OpenCV. Frames are written as PNGs under pytest's tmp dir (``-s`` prints
the paths)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from robot_daemon.vision.ball_finder import BallFinder, FinderSettings
from tests.fixtures.sim_rig import SimRig

BALLS = [(0.5, 0.1), (0.35, -0.2), (0.9, 0.3)]


def gl_rig(seed: int = 3) -> SimRig:
    rig = SimRig(seed=seed, physics="mujoco", vision_fps=1.0)
    rig.world.place_robot(0.0, 0.0, 0.0)
    rig.run(0.5)
    return rig


def test_the_ball_finder_sees_the_ball_in_mujoco_frames_where_opencv_draws_it(
    tmp_path: Path,
) -> None:
    rig = gl_rig()
    world = rig.world
    finder = BallFinder(FinderSettings.from_config(rig.settings.get("ballplay", {})))
    for k, (x, y) in enumerate(BALLS):
        world.place_ball(x, y)
        rig.run(0.1)
        frame = world.render()
        if world.camera.unavailable:
            pytest.skip(f"no OpenGL backend: {world.camera.unavailable}")
        assert world.camera.renderer.startswith("mujoco-")
        reference = world._render_opencv()
        path = tmp_path / f"ball-{k}.png"
        assert cv2.imwrite(str(path), np.hstack([frame, reference]))
        print(f"mujoco | opencv: {path}")
        seen, drawn = finder.find(frame), finder.find(reference)
        assert seen.found and drawn.found, (k, seen, drawn)
        # The same camera pose and lens: the two pictures put the ball on the same pixels.
        assert abs(seen.x - drawn.x) < 4 and abs(seen.y - drawn.y) < 4, (k, seen, drawn)
        # A ball to the robot's left is left in the picture.
        assert (seen.pan_error > 0) == (y > 0.0)


def test_frames_follow_the_simulation(tmp_path: Path) -> None:
    rig = gl_rig(4)
    world = rig.world
    world.place_ball(0.5, 0.15)
    rig.run(0.1)
    before = world.render()
    if world.camera.unavailable:
        pytest.skip(f"no OpenGL backend: {world.camera.unavailable}")
    world.place_ball(0.5, -0.15)  # from the left of the picture to the right
    rig.run(0.1)
    after = world.render()
    finder = BallFinder(FinderSettings.from_config(rig.settings.get("ballplay", {})))
    a, b = finder.find(before), finder.find(after)
    assert a.found and b.found
    assert a.x < 160 < b.x, (a, b)
    assert world.camera.renderer.startswith("mujoco-")


def test_without_gl_the_world_draws_with_opencv(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MUJOCO_GL", "disable")
    rig = gl_rig(5)
    world = rig.world
    world.place_ball(0.5, 0.1)
    rig.run(0.1)
    frame = world.render()
    assert world.camera.renderer == "opencv" and world.camera.mujoco is None
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    finder = BallFinder(FinderSettings.from_config(rig.settings.get("ballplay", {})))
    assert finder.find(frame).found
