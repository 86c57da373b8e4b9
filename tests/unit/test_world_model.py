"""The world model alone: odometry from the legs, falls and the IMU, the ball, the control ops."""

from __future__ import annotations

import math

import cv2
import msgpack
import numpy as np
import pytest

from robot_daemon.emulator.control_service import handle_request
from robot_daemon.motion.walking.ik import leg_ik
from robot_daemon.plant import world_ops
from robot_daemon.plant.ball import Ball
from robot_daemon.plant.world import SimWorld
from robot_daemon.plant.world_settings import BallSettings, FeetSettings, WorldSettings
from schemas import units
from schemas.kinematics import leg_angles_to_servo
from schemas.messages import World, decode, encode

DT = 0.008


def stance(knee: float = 0.6, lean: float = 0.0) -> dict[int, float]:
    """Both legs bent the same way (leg angles: hip pitch −knee/2, ankle pitch −knee/2),
    ``lean`` rad more forward at the ankles."""
    out: dict[int, float] = {19: 0.0, 20: 0.0}
    for side in ("right", "left"):
        out.update(leg_angles_to_servo((0.0, 0.0, -knee / 2, knee, -knee / 2 - lean, 0.0), side))
    return out


def world() -> SimWorld:
    return SimWorld(WorldSettings(robot_start=(0.0, 0.0, 0.0), ball_start=None), seed=1)


def test_standing_still_stays_put_upright() -> None:
    w = world()
    for _ in range(100):
        gyro, accel = w.step(DT, stance())
    snap = w.snapshot()
    assert (snap.robot["x"], snap.robot["y"], snap.robot["yaw"]) == pytest.approx(
        (0, 0, 0), abs=1e-9
    )
    assert snap.fallen == "none"
    assert accel == pytest.approx([0.0, 0.0, units.GRAVITY], abs=1e-6)
    assert gyro == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)


def feet(right: tuple[float, float, float], left: tuple[float, float, float]) -> dict[int, float]:
    """Servo angles putting each sole (flat) at (x, y, z) from its hip point."""
    out: dict[int, float] = {19: 0.0, 20: 0.0}
    for side, p in (("right", right), ("left", left)):
        target = np.eye(4)
        target[:3, 3] = p
        angles = leg_ik(target)
        assert angles is not None
        out.update(leg_angles_to_servo(angles, side))
    return out


def test_the_support_foot_stays_and_the_body_moves_with_the_legs() -> None:
    """Stand on the left foot, swing the right one 4 cm forward and put it down lower: it takes
    the weight; bringing it back under the hip carries the body 4 cm forward."""
    w = world()
    home = (0.0, 0.0, -0.19)
    w.step(DT, feet(home, home))
    for _ in range(10):
        w.step(DT, feet((0.04, 0.0, -0.17), home))  # right foot lifted and forward
    assert w.body.support == "left"
    assert w.snapshot().robot["x"] == pytest.approx(0.0, abs=1e-6)
    for _ in range(10):
        w.step(DT, feet((0.04, 0.0, -0.195), home))  # put down, lower than the left
    assert w.body.support == "right"
    x_planted = w.snapshot().robot["x"]
    for _ in range(10):
        w.step(DT, feet(home, home))  # the body moves over the planted foot
    assert w.snapshot().robot["x"] == pytest.approx(x_planted + 0.04, abs=1e-3)
    assert w.snapshot().fallen == "none"


def test_leaning_far_forward_falls_forward_and_the_imu_says_so() -> None:
    w = world()
    lean = 0.0
    while w.snapshot().fallen == "none" and lean < 1.2:
        lean += 0.01
        _, accel = w.step(DT, stance(lean=lean))
    assert w.snapshot().fallen == "forward"
    assert w.falls == 1
    # The CM-730 counts the framework reads: accel Y (robot x) below 390 is fallen forward.
    assert units.ms2_to_accel_raw(accel[0]) < 390


def test_leaning_back_falls_backward() -> None:
    w = world()
    lean = 0.0
    while w.snapshot().fallen == "none" and lean > -1.2:
        lean -= 0.01
        _, accel = w.step(DT, stance(lean=lean))
    assert w.snapshot().fallen == "backward"
    assert units.ms2_to_accel_raw(accel[0]) > 580


def test_a_get_up_motion_stands_the_robot_up_again() -> None:
    w = world()
    lean = 0.0
    while w.snapshot().fallen == "none":
        lean += 0.02
        w.step(DT, stance(lean=lean))
    # Lying there does nothing; a crouch then standing up does.
    for _ in range(20):
        w.step(DT, stance(lean=lean))
    assert w.snapshot().fallen == "forward"
    for _ in range(20):
        w.step(DT, stance(knee=2.6))  # crouched: body low over the feet
    assert w.snapshot().fallen == "forward"
    for _ in range(20):
        _, accel = w.step(DT, stance(knee=0.6))
    assert w.snapshot().fallen == "none"
    assert units.ms2_to_accel_raw(accel[0]) == pytest.approx(512, abs=5)


def test_place_robot_sets_the_pose_and_clears_a_fall() -> None:
    w = world()
    w.step(DT, stance())
    w.place_robot(1.5, -0.5, math.radians(90))
    w.step(DT, stance())
    r = w.snapshot().robot
    assert (r["x"], r["y"], r["yaw"]) == pytest.approx((1.5, -0.5, math.pi / 2), abs=1e-6)


def test_the_ball_rolls_and_stops_by_friction() -> None:
    s = BallSettings(rolling_decel=0.5)
    ball = Ball(s, FeetSettings())
    ball.place(0.0, 0.0, 1.0, 0.0)
    for _ in range(int(3.0 / DT)):
        ball.step(DT, [])
    assert ball.state.speed == 0.0
    # v² / (2·a) = 1 m, give or take a step.
    assert ball.state.x == pytest.approx(1.0, abs=0.02)


def sole(x: float, y: float) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = (x, y, 0.0)
    return t


@pytest.mark.parametrize("foot_speed", [0.3, 1.0])
def test_a_foot_sweeping_through_the_ball_sends_it_with_its_speed(foot_speed: float) -> None:
    s = BallSettings(restitution=0.5, rolling_decel=0.0)
    ball = Ball(s, FeetSettings())
    ball.place(0.10, 0.0)
    x = 0.0
    for _ in range(30):
        x += foot_speed * DT
        ball.step(DT, [(sole(x, 0.0), np.array([foot_speed, 0.0, 0.0]))])
    assert ball.touches >= 1
    assert ball.state.vx == pytest.approx(1.5 * foot_speed, rel=0.05)
    assert abs(ball.state.vy) < 1e-6


def test_a_foot_beside_the_ball_does_not_touch_it() -> None:
    ball = Ball(BallSettings(), FeetSettings())
    ball.place(0.10, 0.2)
    ball.step(DT, [(sole(0.1, 0.0), np.array([1.0, 0.0, 0.0]))])
    assert ball.touches == 0 and ball.state.speed == 0.0


class _Emu:
    def __init__(self) -> None:
        self.world = world()


def call(emu: _Emu, **request) -> tuple[bool, dict]:
    world_ops.install()
    ok, payload = handle_request(emu, request)  # type: ignore[arg-type]
    return ok, msgpack.unpackb(payload)


def test_control_ops_place_and_remove_the_ball() -> None:
    emu = _Emu()
    ok, reply = call(emu, op="place_ball", x=0.5, y=-0.25)
    assert ok and reply["applied"]["ball"]["x"] == 0.5
    ok, reply = call(emu, op="get_world")
    assert ok and reply["applied"]["ball"]["y"] == -0.25
    ok, _ = call(emu, op="remove_ball")
    assert ok and emu.world.ball.state is None


@pytest.mark.parametrize(
    ("request_", "field"),
    [
        ({"op": "place_ball", "x": "near", "y": 0.0}, "x"),
        ({"op": "place_ball", "x": 0.0}, "y"),
        ({"op": "place_robot", "x": 0.0, "y": 1e9}, "y"),
        ({"op": "place_robot", "x": 0.0, "y": 0.0, "yaw": float("nan")}, "yaw"),
    ],
)
def test_bad_control_requests_name_the_field_and_change_nothing(request_, field) -> None:
    emu = _Emu()
    before = emu.world.snapshot()
    ok, reply = call(emu, **request_)
    assert not ok
    assert reply["field"] == field
    after = emu.world.snapshot()
    assert (after.robot, after.ball) == (before.robot, before.ball)


def test_world_message_round_trips_through_msgpack() -> None:
    w = SimWorld(WorldSettings(), seed=1)
    w.step(DT, stance())
    msg = decode(encode(w.snapshot()), World)
    assert set(msg.robot) == {"x", "y", "yaw"}
    assert set(msg.ball) == {"x", "y", "vx", "vy"}


def test_render_op_gives_a_frame_with_the_ball() -> None:
    emu = _Emu()
    emu.world.step(DT, stance())
    emu.world.place_ball(0.4, 0.0)
    ok, reply = call(emu, op="render")
    a = reply["applied"]
    img = np.frombuffer(a["bgr"], np.uint8).reshape(a["height"], a["width"], 3)
    assert ok and img.shape == (240, 320, 3)
    red = (img[..., 2] > 120) & (img[..., 1] < 80) & (img[..., 0] < 80)
    assert red.sum() > 30


def test_render_op_gives_the_jpeg_a_camera_would_and_refuses_bad_formats() -> None:
    emu = _Emu()
    emu.world.step(DT, stance())
    emu.world.place_ball(0.4, 0.0)
    ok, reply = call(emu, op="render", format="jpeg", quality=90)
    a = reply["applied"]
    assert ok and "bgr" not in a and a["jpeg"].startswith(b"\xff\xd8")
    img = cv2.imdecode(np.frombuffer(a["jpeg"], np.uint8), cv2.IMREAD_COLOR)
    assert img.shape == (a["height"], a["width"], 3) == (240, 320, 3)
    red = (img[..., 2] > 120) & (img[..., 1] < 80) & (img[..., 0] < 80)
    assert red.sum() > 30
    for bad, field in (({"format": "png"}, "format"), ({"quality": 0}, "quality")):
        ok, reply = call(emu, op="render", **bad)
        assert not ok and reply["field"] == field


def test_push_tips_the_kinematic_body_the_way_it_was_pushed_above_the_threshold() -> None:
    w = world()
    for _ in range(10):
        w.step(DT, stance())
    w.push((2.0, 0.0, 0.0), 0.1)  # 0.2 N·s: below push_fall_impulse, nothing happens
    assert w.snapshot().fallen == "none"
    w.push((-10.0, 0.0, 0.0), 0.1)  # 1 N·s toward its back
    assert w.snapshot().fallen == "backward" and w.falls == 1
    _, accel = w.step(DT, stance())
    assert units.ms2_to_accel_raw(accel[0]) > 580  # the framework's "fallen backward"
    w.place_robot(0.0, 0.0, math.pi / 2)  # facing +y
    w.step(DT, stance())
    w.push((0.0, 10.0, 0.0), 0.1)
    assert w.snapshot().fallen == "forward"
