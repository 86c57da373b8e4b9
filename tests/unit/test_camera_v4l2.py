"""The V4L2 MJPEG camera against a fake UVC camera at the system-call seam
(``tests/fixtures/fake_v4l2.py``), and the camera thread's passthrough of its JPEG bytes: viewers
get the camera's own bytes, vision decodes only the frames it reads, and all of it runs with
OpenCV absent from the daemon."""

from __future__ import annotations

import ctypes
import os
import platform
import subprocess
import sys
import threading
import uuid
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
import zenoh

from config.loader import load_all
from robot_daemon.engine.camera import CameraThread
from robot_daemon.vision import v4l2
from robot_daemon.vision.frames import JpegFrame
from robot_daemon.vision.sources import register_source
from robot_daemon.vision.v4l2 import V4L2Error, V4L2Source
from schemas.keys import Keys
from schemas.messages import CameraFrame, decode
from schemas.session import free_tcp_port, server_config
from tests.fixtures import fake_v4l2
from tests.fixtures.fake_v4l2 import YUYV, FakeCamera

REPO = Path(__file__).resolve().parents[2]
WAIT = 15.0
pytestmark = pytest.mark.skipif(
    platform.machine() != "x86_64", reason="the fake camera speaks the x86-64 kernel ABI"
)


def jpegs(n: int = 3, size: tuple[int, int] = (320, 240)) -> list[bytes]:
    """``n`` distinct JPEG files: a red ball at a different place in each."""
    out = []
    for i in range(n):
        img = np.full((size[1], size[0], 3), 40, np.uint8)
        cv2.circle(img, (60 + 80 * i, 120), 30, (0, 0, 230), -1)
        ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])
        assert ok
        out.append(data.tobytes())
    return out


@pytest.fixture
def session() -> Iterator[zenoh.Session]:
    s = zenoh.open(server_config([f"tcp/127.0.0.1:{free_tcp_port()}"]))
    yield s
    s.close()


def test_the_ioctl_numbers_are_the_kernels() -> None:
    assert v4l2.VIDIOC_QUERYCAP == fake_v4l2.QUERYCAP
    assert v4l2.VIDIOC_S_FMT == fake_v4l2.S_FMT
    assert v4l2.VIDIOC_REQBUFS == fake_v4l2.REQBUFS
    assert (v4l2.VIDIOC_QUERYBUF, v4l2.VIDIOC_QBUF, v4l2.VIDIOC_DQBUF) == (
        fake_v4l2.QUERYBUF, fake_v4l2.QBUF, fake_v4l2.DQBUF,
    )  # fmt: skip
    assert (v4l2.VIDIOC_STREAMON, v4l2.VIDIOC_STREAMOFF, v4l2.VIDIOC_S_PARM) == (
        fake_v4l2.STREAMON, fake_v4l2.STREAMOFF, fake_v4l2.S_PARM,
    )  # fmt: skip
    assert v4l2.Buffer.m.offset == fake_v4l2.B_OFFSET
    assert v4l2.Buffer.length.offset == fake_v4l2.B_LENGTH
    assert v4l2.Buffer.sequence.offset == fake_v4l2.B_SEQ


def test_asks_for_mjpeg_and_gives_the_cameras_own_bytes_in_turn() -> None:
    frames = jpegs(3)
    cam = FakeCamera(frames)
    src = V4L2Source(cam.path, 320, 240, 25.0, device=cam)
    assert cam.fmt == (320, 240, fake_v4l2.MJPG)
    assert cam.fps_asked == pytest.approx(25.0)
    assert (src.info.card, src.info.width, src.info.height) == ("Fake UVC Camera", 320, 240)
    assert cam.calls[:2] == ["QUERYCAP", "S_FMT"] and "STREAMON" in cam.calls
    got = [src.read() for _ in range(10)]  # more reads than buffers: each is queued again
    assert all(isinstance(f, JpegFrame) for f in got)
    assert [f.jpeg for f in got if f] == [frames[i % 3] for i in range(10)]
    assert {(f.width, f.height) for f in got if f} == {(320, 240)}
    src.close()
    assert cam.calls[-2:] == ["STREAMOFF", "close"] and not cam.open_fds


def test_a_size_the_camera_lacks_is_the_nearest_it_has() -> None:
    cam = FakeCamera(jpegs(1, (640, 480)))
    src = V4L2Source(cam.path, 600, 400, 30.0, device=cam)
    frame = src.read()
    assert frame is not None and (frame.width, frame.height) == (640, 480)
    src.close()


def test_bad_frames_are_skipped_and_a_stalled_camera_gives_none() -> None:
    frames = jpegs(2)
    cam = FakeCamera([frames[0], b"\x00\x01truncated", frames[1]], bad={3})
    src = V4L2Source(cam.path, 320, 240, 30.0, device=cam)
    got = [src.read() for _ in range(5)]
    assert [f.jpeg if f else None for f in got] == [frames[0], None, frames[1], None, None]
    assert src.dropped == 3  # the cut one (twice: frames come in turn) and the flagged one
    cam.streaming = False  # nothing arrives any more
    assert src.read() is None
    src.close()


def test_cameras_that_cannot_do_it_are_refused_in_one_line_naming_the_fix() -> None:
    with pytest.raises(V4L2Error, match=r"plugged in.*--camera none"):
        V4L2Source("/dev/video9", 320, 240, 30.0, device=FakeCamera(jpegs(1)))
    yuyv = FakeCamera(jpegs(1), formats=(YUYV,))
    with pytest.raises(V4L2Error, match=r"does not offer MJPEG.*list-formats"):
        V4L2Source(yuyv.path, 320, 240, 30.0, device=yuyv)
    assert not yuyv.open_fds  # closed on the way out
    meta = FakeCamera(jpegs(1), capture=False)
    with pytest.raises(V4L2Error, match="not a streaming capture device"):
        V4L2Source(meta.path, 320, 240, 30.0, device=meta)


def test_structures_of_the_wrong_size_fail_as_the_kernel_would() -> None:
    cam = FakeCamera(jpegs(1))
    fd = cam.open(cam.path)
    with pytest.raises(OSError, match="argument of 4 bytes"):
        cam.ioctl(fd, fake_v4l2.QUERYCAP, ctypes.c_int(0))


def test_the_camera_thread_passes_the_jpeg_through_and_vision_decodes_what_it_reads(
    session: zenoh.Session,
) -> None:
    frames = jpegs(3)
    cam = FakeCamera(frames)
    spec = f"fakeuvc-{uuid.uuid4().hex[:6]}"
    register_source(spec, lambda ctx: V4L2Source(cam.path, 320, 240, ctx.fps, device=cam))
    keys = Keys(f"t{uuid.uuid4().hex[:8]}")
    camera = CameraThread.from_settings(session, keys, spec, load_all())
    got: list[CameraFrame] = []
    enough = threading.Event()

    def on_frame(sample: zenoh.Sample) -> None:
        msg = decode(sample.payload.to_bytes())
        assert isinstance(msg, CameraFrame)
        got.append(msg)
        if len(got) >= 6:
            enough.set()

    sub = session.declare_subscriber(keys.camera_jpeg, on_frame)
    reader = camera.consumer()
    try:
        assert enough.wait(WAIT), "no camera frames reached the subscriber"
        # Viewers get the camera's own bytes, with the message's fields as before.
        assert all(m.jpeg in frames and (m.width, m.height) == (320, 240) for m in got)
        img = reader.read(WAIT)
        assert img is not None and img.shape == (240, 320, 3)
        assert any(np.array_equal(img, cv2.imdecode(np.frombuffer(f, np.uint8), 1)) for f in frames)
        assert reader.decoded == 1  # frames it did not read were never decoded
    finally:
        reader.close()
        sub.undeclare()
        camera.close()
    # Counted once the thread has stopped: a status read mid-frame may fall between the two.
    st = camera.status()
    assert st["passed_through"] == st["published"] >= 6
    assert not cam.open_fds


NO_OPENCV = """
import sys, threading
sys.modules["cv2"] = None  # as on a robot without the vision extra
from pathlib import Path
import zenoh
from config.loader import load_all
from robot_daemon.engine.camera import CameraThread
from schemas.extras import MissingExtraError
from robot_daemon.vision.sources import register_source
from robot_daemon.vision.v4l2 import V4L2Source
from schemas.keys import Keys
from schemas.messages import decode
from schemas.session import free_tcp_port, server_config
from tests.fixtures.fake_v4l2 import FakeCamera

frames = [Path(p).read_bytes() for p in sys.argv[1:]]
cam = FakeCamera(frames)
register_source("fakeuvc", lambda ctx: V4L2Source(cam.path, 320, 240, ctx.fps, device=cam))
with zenoh.open(server_config([f"tcp/127.0.0.1:{free_tcp_port()}"])) as s:
    camera = CameraThread.from_settings(s, Keys("nocv"), "fakeuvc", load_all())
    got, seen = [], threading.Event()
    sub = s.declare_subscriber(Keys("nocv").camera_jpeg,
                               lambda x: (got.append(decode(x.payload.to_bytes())), seen.set()))
    assert seen.wait(15), "no frame"
    assert got[0].jpeg in frames, "not the camera's bytes"
    reader = camera.consumer()
    try:
        reader.read(15)
    except MissingExtraError as exc:
        print("vision:", exc)
    reader.close()
    sub.undeclare()
    camera.close()
print("passthrough ok without cv2")
"""


def test_the_passthrough_runs_without_opencv_and_vision_says_which_extra(tmp_path: Path) -> None:
    paths = []
    for i, data in enumerate(jpegs(2)):
        paths.append(tmp_path / f"f{i}.jpg")
        paths[-1].write_bytes(data)
    proc = subprocess.run(
        [sys.executable, "-c", NO_OPENCV, *map(str, paths)],
        capture_output=True, text=True, cwd=REPO, timeout=120,
        env=dict(os.environ, PYTHONPATH=str(REPO)),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[-1] == "passthrough ok without cv2"
    (vision,) = [ln for ln in lines if ln.startswith("vision:")]
    assert "needs the 'vision' extra" in vision and "python3-opencv" in vision
