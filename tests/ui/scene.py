"""A fixed scene for the UI tests and snapshots: deterministic joints, IMU history, status,
events, a camera frame with a ball, a behaviour library. No clocks: every stamp is fixed."""

from __future__ import annotations

import functools
import math
from typing import Any

import cv2
import numpy as np

from clients.tui.app import DarwinApp
from clients.tui.messages import LinkChanged, LinkInfo, LinkState
from config.loader import RobotConfig, load_robot
from schemas.messages import BallDetection, CameraFrame, Event, Imu, Joints, Status

T0 = 1_700_000_000.0  # 2023-11-14 22:13:20 UTC
ENDPOINT = "tcp/127.0.0.1:7447"
ROBOT = "op1"
ME = "tui-client-1"

LIBRARY: list[dict[str, Any]] = [
    {"id": "stand", "name": "stand up", "kind": "action", "page": 1},
    {"id": "bow", "name": "bow", "kind": "action", "page": 15},
    {"id": "walk_fwd", "name": "walk forward", "kind": "walk", "duration": 3.0, "x": 0.04},
    {"id": "wave", "name": "wave", "kind": "action", "page": 38},
    {"id": "pause", "name": "pause", "kind": "pause", "duration": 1.0},
]
WALK_PARAMS: dict[str, Any] = {
    "period_time": 600.0,
    "dsp_ratio": 0.1,
    "step_fb_ratio": 0.28,
    "foot_height": 40.0,
    "swing_right_left": 20.0,
    "swing_top_down": 5.0,
    "pelvis_offset": 3.0,
    "arm_swing_gain": 1.5,
    "hip_pitch_offset": 13.0,
    "x_offset": -10.0,
}


@functools.cache
def _robot() -> RobotConfig:
    return load_robot()


def joints(tick: int = 0, stamp: float = T0) -> Joints:
    robot = _robot()
    ids = list(robot.ids)
    base = [math.radians(((i * 37) % 30) - 15) * 0.5 for i in ids]
    pos = [b + 0.05 * math.sin(tick / 20 + i) for i, b in enumerate(base)]
    return Joints(
        id=ids,
        name=[robot.joint(i).name for i in ids],
        position=pos,
        goal=base,
        velocity=[0.1 * (i % 3) for i in ids],
        load=[0.05 * ((i % 5) - 2) for i in ids],
        temperature=[38.0 + i % 7 for i in ids],
        voltage=[12.1] * len(ids),
        torque_enabled=[i != 20 for i in ids],
        online=[i != 17 for i in ids],
        alarm=[0x20 if i == 9 else 0 for i in ids],
        stamp=stamp,
        tick=tick,
    )


def imu(k: int) -> Imu:
    t = k * 0.04
    accel = [0.8 * math.sin(t * 2.0), 0.5 * math.cos(t * 1.3), 9.81 + 0.3 * math.sin(t * 3.1)]
    gyro = [0.4 * math.sin(t * 1.7), 0.2 * math.sin(t * 2.9 + 1), 0.1 * math.cos(t * 0.9)]
    return Imu(
        gyro=gyro, accel=accel, gyro_raw=[512] * 3, accel_raw=[512] * 3, stamp=T0 + t, tick=k
    )


def status(lease_client: str | None = ME, walking: bool = True) -> Status:
    lease = {"client": lease_client, "name": "tui", "since": T0} if lease_client else None
    return Status(
        state="running",
        robot=ROBOT,
        lease=lease,
        motion={
            "walking": {"x": 0.04, "y": 0.0, "turn": 0.0} if walking else False,
            "ball": {"phase": "track", "running": True},
        },
        choreography={"playing": True, "index": 1},
        loop={"period_p50_ms": 8.0, "overruns": 2, "tick_ms": 8.0},
        voltage=12.1,
        alarms=[{"id": 9, "message": "r_hip_roll overheating"}],
        stamp=T0,
    )


def frame() -> tuple[CameraFrame, BallDetection]:
    h, w = 240, 320
    yy, _xx = np.mgrid[0:h, 0:w]
    img = np.zeros((h, w, 3), np.uint8)
    img[..., 1] = 90 + (yy * 80 // h)  # green field, lighter towards the robot
    img[..., 0] = 40
    img[: h // 3] = (200, 170, 150)  # a wall above the horizon (BGR)
    cv2.line(img, (0, 150), (w, 130), (255, 255, 255), 3)
    cv2.circle(img, (200, 170), 18, (30, 30, 230), -1)  # the red ball
    ok, jpeg = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    cam = CameraFrame(jpeg=jpeg.tobytes(), width=w, height=h, seq=1234, stamp=T0)
    ball = BallDetection(
        found=True, x=200, y=170, size=0.013, width=w, height=h, phase="track", stamp=T0
    )
    return cam, ball


EVENTS = [
    Event(kind="lease", message="tui took the control lease", seq=1, stamp=T0 - 30),
    Event(kind="choreography_started", message="choreography of 3 items", seq=2, stamp=T0 - 20),
    Event(kind="servo_alarm", message="servo 9 (r_hip_roll): overheating", seq=3, stamp=T0 - 10),
    Event(kind="fall", message="the robot fell forward", seq=4, stamp=T0 - 5),
]


def load_scene(app: DarwinApp) -> None:
    """Put the scene in the app's model (the messages the link would have delivered)."""
    m = app.model
    m.client_id = ME
    for k in range(250):
        m.add_imu(imu(k))
    for k in range(0, 250, 2):
        m.add_joints(joints(k, T0 + k * 0.04))
    m.add_status(status())
    cam, ball = frame()
    m.add_frame(cam)
    m.add_ball(ball)
    for e in EVENTS:
        m.add_event(e)
    m.edits.behaviours = [dict(e) for e in LIBRARY]
    m.edits.walk_params = dict(WALK_PARAMS)
    m.bump("library")
    m.bump("params")
    m.edits.choreography = [
        {"behaviour": "stand"},
        {"behaviour": "walk_fwd", "duration": 3.0, "x": 0.04},
        {"behaviour": "bow"},
    ]
    app.post_message(LinkChanged(LinkInfo(LinkState.CONNECTED, ENDPOINT, ROBOT)))
