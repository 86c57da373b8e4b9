"""The MuJoCo head camera: offscreen on the CPU, a thread of its own, BGR frames where the
projection says.

A small scene written here (a plane, a red ball on a free joint, a level camera) is rendered and
the red pixels' centroid compared with the pinhole projection of the ball's centre. Each test
writes its frame as a PNG under pytest's tmp dir (the path is printed; run with ``-s`` to see
it) for a person to look at.
"""

from __future__ import annotations

import gc
import math
import os
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip(
    "mujoco", reason="needs the physics extra: pip install -e '.[physics]'"
)
cv2 = pytest.importorskip("cv2")

from robot_daemon.plant.physics.mujoco_camera import (  # noqa: E402
    GLUnavailableError,
    MujocoCamera,
    WorldCamera,
)
from schemas.errors import CameraError  # noqa: E402

W, H, FOVY = 320, 240, 46.0
CAM_POS = np.array([0.0, 0.0, 0.3])
# MuJoCo cameras look along their −z with x to the right and y up: this one looks along the
# world's +x, level.
CAM_RIGHT, CAM_UP = np.array([0.0, -1.0, 0.0]), np.array([0.0, 0.0, 1.0])
RADIUS = 0.05

SCENE = f"""
<mujoco>
  <visual><global offwidth="{W}" offheight="{H}"/></visual>
  <worldbody>
    <light pos="0 0 3" dir="0 0 -1" directional="true"/>
    <geom name="floor" type="plane" size="5 5 0.1" rgba="0.2 0.6 0.2 1"/>
    <camera name="head_camera" pos="{CAM_POS[0]} {CAM_POS[1]} {CAM_POS[2]}"
            xyaxes="0 -1 0 0 0 1" fovy="{FOVY}"/>
    <body name="ball" pos="1 0.2 {RADIUS}">
      <freejoint/>
      <geom name="ball" type="sphere" size="{RADIUS}" rgba="0.9 0.05 0.05 1"/>
    </body>
  </worldbody>
</mujoco>
"""


def expected_pixel(ball: np.ndarray) -> tuple[float, float]:
    """The pinhole projection of the ball's centre (u right, v down, pixel centres at +0.5)."""
    rel = ball - CAM_POS
    depth = rel[0]
    f = (H / 2) / math.tan(math.radians(FOVY) / 2)
    return W / 2 + f * (rel @ CAM_RIGHT) / depth, H / 2 - f * (rel @ CAM_UP) / depth


def red_centroid(bgr: np.ndarray) -> tuple[float, float, int]:
    b, g, r = (bgr[..., i].astype(int) for i in range(3))
    mask = (r > 60) & (r > 2 * g + 30) & (r > 2 * b + 30)
    vs, us = np.nonzero(mask)
    assert us.size, "no red pixels in the frame"
    return float(us.mean() + 0.5), float(vs.mean() + 0.5), int(us.size)


def save(tmp_path: Path, name: str, bgr: np.ndarray) -> None:
    path = tmp_path / f"{name}.png"
    assert cv2.imwrite(str(path), bgr)
    print(f"frame: {path}")


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(SCENE)


@pytest.fixture(scope="module")
def camera(model: mujoco.MjModel) -> Iterator[MujocoCamera]:
    try:
        cam = MujocoCamera(model, W, H)
    except GLUnavailableError as exc:
        pytest.skip(f"no OpenGL backend for offscreen rendering: {exc}")
    with cam:
        yield cam


def place_ball(model: mujoco.MjModel, data: mujoco.MjData, pos: np.ndarray) -> None:
    adr = int(model.jnt_qposadr[0])  # the ball's free joint: position, then quaternion
    data.qpos[adr : adr + 3] = pos
    data.qpos[adr + 3 : adr + 7] = (1.0, 0.0, 0.0, 0.0)
    mujoco.mj_forward(model, data)


def test_the_ball_appears_where_the_projection_puts_it(
    model: mujoco.MjModel, camera: MujocoCamera, tmp_path: Path
) -> None:
    data = mujoco.MjData(model)
    ball = np.array([1.0, 0.2, RADIUS])
    place_ball(model, data, ball)
    frame = camera.render(data)
    save(tmp_path, "ball-left-low", frame)
    assert frame.shape == (H, W, 3) and frame.dtype == np.uint8
    u, v, n = red_centroid(frame)
    eu, ev = expected_pixel(ball)
    # Left of centre (the ball is to the left) and below the horizon (it is below the camera):
    # a frame upside down or mirrored, or RGB where BGR is due, fails here.
    assert abs(u - eu) < 2.0 and abs(v - ev) < 2.0, ((u, v), (eu, ev))
    f = (H / 2) / math.tan(math.radians(FOVY) / 2)
    disc = math.pi * (f * RADIUS / float(np.linalg.norm(ball - CAM_POS))) ** 2
    assert 0.7 * disc < n < 1.3 * disc, (n, disc)
    # Above the horizon there is no floor: the top rows are not green.
    top = frame[:20].reshape(-1, 3).mean(axis=0)
    bottom = frame[-20:].reshape(-1, 3).mean(axis=0)
    assert bottom[1] > bottom[2] + 20 and bottom[1] > top[1] + 20, (top, bottom)


def test_renders_a_copy_of_the_state_taken_when_asked(
    model: mujoco.MjModel, camera: MujocoCamera, tmp_path: Path
) -> None:
    data = mujoco.MjData(model)
    first = np.array([1.5, -0.3, RADIUS])
    place_ball(model, data, first)
    state = camera.capture(data)
    place_ball(model, data, np.array([0.8, 0.3, RADIUS]))  # physics moves on
    u, v, _ = red_centroid(camera.render(state))
    eu, ev = expected_pixel(first)
    assert abs(u - eu) < 2.0 and abs(v - ev) < 2.0, ((u, v), (eu, ev))
    frame = camera.render(data)
    save(tmp_path, "ball-moved", frame)
    u2, _, _ = red_centroid(frame)
    assert abs(u2 - expected_pixel(np.array([0.8, 0.3, RADIUS]))[0]) < 2.0


def test_frames_come_from_the_cameras_own_thread_whoever_asks(
    model: mujoco.MjModel, camera: MujocoCamera
) -> None:
    data = mujoco.MjData(model)
    place_ball(model, data, np.array([1.0, 0.0, RADIUS]))
    frames: list[np.ndarray] = []
    errors: list[BaseException] = []

    def ask() -> None:
        try:
            for _ in range(3):
                frames.append(camera.render(camera.capture(data)))
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=ask) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert len(frames) == 9
    assert all(np.array_equal(frames[0], f) for f in frames[1:])


def test_bad_requests_name_what_is_wrong(model: mujoco.MjModel, camera: MujocoCamera) -> None:
    with pytest.raises(CameraError, match="no camera named 'eye'"):
        MujocoCamera(model, W, H, camera="eye")
    other = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    with pytest.raises(CameraError, match="qpos"):
        camera.render(mujoco.MjData(other))


def test_closed_camera_refuses_frames(model: mujoco.MjModel, camera: MujocoCamera) -> None:
    cam = MujocoCamera(model, 64, 48)
    assert cam.render(mujoco.MjData(model)).shape == (48, 64, 3)
    cam.close()
    cam.close()  # twice is fine
    with pytest.raises(CameraError, match="closed"):
        cam.render(mujoco.MjData(model))


def test_without_a_gl_backend_it_says_so_in_one_line() -> None:
    """PyOpenGL bound to a platform neither backend can use: what a machine without EGL and
    OSMesa looks like to the camera. The world catches this error and draws with OpenCV."""
    code = (
        "import mujoco\n"
        "from robot_daemon.plant.physics.mujoco_camera import GLUnavailableError, MujocoCamera\n"
        f"m = mujoco.MjModel.from_xml_string({SCENE!r})\n"
        "try:\n"
        "    MujocoCamera(m, 32, 24)\n"
        "except GLUnavailableError as exc:\n"
        "    print('error:', exc)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    env["PYOPENGL_PLATFORM"] = "glx"
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: no OpenGL backend"), out.stdout
    assert "egl:" in lines[0] and "osmesa:" in lines[0] and "apt-get install" in lines[0]


def test_a_camera_still_open_at_exit_ends_its_thread_before_the_interpreter_finalizes(
    camera: MujocoCamera,
) -> None:
    """A program that exits holding a camera: its render thread frees GL and ends while Python
    can still run it (a daemon thread left to finalization died with a traceback). The hook
    registered first runs last, after the camera module's own, and sees what is still alive."""
    code = (
        "import atexit, threading\n"
        "def last():\n"
        "    alive = [t.name for t in threading.enumerate() if 'mujoco-camera' in t.name]\n"
        "    print('alive at exit:', alive, flush=True)\n"
        "atexit.register(last)\n"
        "import mujoco\n"
        "from robot_daemon.plant.physics.mujoco_camera import MujocoCamera\n"
        f"m = mujoco.MjModel.from_xml_string({SCENE!r})\n"
        "cam = MujocoCamera(m, 32, 24)\n"
        "cam.render(mujoco.MjData(m))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "alive at exit: []", out.stdout
    assert "Traceback" not in out.stderr and "Exception in thread" not in out.stderr, out.stderr


def test_the_world_camera_starts_on_the_first_frame_and_draws_with_mujoco(
    model: mujoco.MjModel, camera: MujocoCamera
) -> None:
    data = mujoco.MjData(model)
    place_ball(model, data, np.array([1.0, 0.2, RADIUS]))
    fallbacks: list[int] = []
    world_cam = WorldCamera(model, W, H, fallback=lambda: fallbacks.append(1) or np.zeros(1))
    assert world_cam.renderer == "not started" and world_cam.mujoco is None  # no GL thread yet
    try:
        frame = world_cam.render(threading.Lock(), data)
        assert world_cam.renderer == f"mujoco-{camera.backend}" and not fallbacks
        u, v, _ = red_centroid(frame)
        eu, ev = expected_pixel(np.array([1.0, 0.2, RADIUS]))
        assert abs(u - eu) < 2.0 and abs(v - ev) < 2.0
    finally:
        world_cam.close()


def test_without_gl_the_world_camera_falls_back_to_opencv(
    model: mujoco.MjModel, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setenv("MUJOCO_GL", "disable")
    opencv = np.full((H, W, 3), 7, dtype=np.uint8)
    world_cam = WorldCamera(model, W, H, fallback=lambda: opencv)
    for _ in range(3):
        assert world_cam.render(threading.Lock(), mujoco.MjData(model)) is opencv
    assert world_cam.renderer == "opencv"
    assert world_cam.unavailable == "MUJOCO_GL=disable turns the MuJoCo camera off"
    warnings = [r for r in caplog.records if "draws with OpenCV" in r.getMessage()]
    assert len(warnings) == 1  # said once, not per frame


def test_a_camera_nobody_holds_any_more_ends_its_thread(model: mujoco.MjModel) -> None:
    """Worlds come and go (every SimRig makes one): their GL threads must not pile up."""
    cam = MujocoCamera(model, 32, 24)
    cam.render(mujoco.MjData(model))
    thread = cam._thread
    del cam
    gc.collect()
    thread.join(timeout=10.0)
    assert not thread.is_alive()
