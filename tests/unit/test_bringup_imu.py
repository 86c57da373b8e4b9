"""Falls only from valid CM-730 data, after the gyro centre is measured (issue 25, findings 1
and 4): the motion manager fed what the bus layer reports before the CM-730 answered."""

from __future__ import annotations

import numpy as np

from config.loader import load_all, load_robot
from robot_daemon.bus.robot_bus import RobotBus
from robot_daemon.frames import JointFrame
from robot_daemon.motion.setup import build_manager
from tests.unit.motion_rig import DT, PerfectServos


def test_the_initial_all_zero_cm730_block_never_starts_a_get_up_page() -> None:
    settings, robot = load_all(), load_robot()
    bus = RobotBus("/dev/null", robot, settings, lambda *a, **k: None)  # never opened
    manager = build_manager(robot, settings)
    for tick in range(400):  # 3.2 s of a CM-730 that has not answered yet
        frame = bus.frame(tick, tick * DT, DT)
        assert not frame.imu_valid
        manager.step(frame)
    events = [(k, m) for k, m, _ in manager.drain_events()]
    assert not [e for e in events if e[0] == "fall"], events
    assert not manager.module("action").status()["playing"]
    assert manager.module("fall").state == "upright"
    assert not manager.module("imu").calibrated  # no valid sample: nothing measured


def _rig(gyro: np.ndarray | None = None) -> tuple[PerfectServos, list[JointFrame]]:
    rig = PerfectServos(build_manager(load_robot(), load_all()))
    return rig, []


def _frame(rig: PerfectServos, accel_x: float, gyro: tuple[float, float, float]) -> JointFrame:
    f = rig.frame()
    f.gyro_raw = np.array(gyro)
    f.accel_raw = np.array([accel_x, 512, 640 if accel_x == 512 else 512])
    return f


def test_no_fall_before_the_gyro_is_calibrated_and_the_centre_is_published() -> None:
    rig, _ = _rig()
    rng = np.random.default_rng(1)
    for _ in range(300):  # face down (1 g along −Y), but moving: the gyro SD is far above 2
        rig.step(_frame(rig, 384, tuple(512 + rng.normal(0, 20, 3))))
    imu = rig.manager.module("imu")
    assert not imu.calibrated and imu.status()["attempts"] == 3
    assert rig.manager.module("fall").falls == 0
    for _ in range(100):  # still and upright: calibrated, centre = the mean (truncated)
        rig.step(_frame(rig, 512, (515.4, 509.0, 512.0)))
    assert imu.calibrated
    assert rig.manager.status()["imu"]["gyro_centre"] == [515.0, 509.0, 512.0]
    for _ in range(40):  # now lying face down on valid data: a fall (no page: nobody's
        rig.step(_frame(rig, 384, (515, 509, 512)))  # motion runs, motion_authority.py)
    assert rig.manager.module("fall").falls == 1
    assert rig.manager.module("fall").state == "fallen_forward"
    assert not rig.manager.module("action").status()["playing"]


def test_invalid_cm730_samples_do_not_enter_the_fall_window() -> None:
    rig, _ = _rig()
    for _ in range(100):
        rig.step(_frame(rig, 512, (512, 512, 512)))
    for _ in range(200):  # the CM-730 missed these reads: stale zeros are not a fall
        f = _frame(rig, 0, (512, 512, 512))
        f.accel_raw = np.zeros(3)
        f.imu_valid = False
        rig.step(f)
    assert rig.manager.module("fall").falls == 0


def test_walking_waits_for_the_gyro_calibration() -> None:
    rig, _ = _rig()
    rig.manager.module("walking").start(0.03, 0, 0)
    for _ in range(99):  # the robot is still: calibrated at the 100th sample
        out = rig.step(_frame(rig, 512, (512, 512, 512)))
        assert not out.goal, "walking moved before the gyro centre was measured"
    moved = [rig.step(_frame(rig, 512, (512, 512, 512))).goal for _ in range(3)]
    assert rig.manager.module("imu").calibrated and all(moved)


def test_a_walk_stopped_while_it_waits_for_the_gyro_never_starts() -> None:
    rig, _ = _rig()
    walking = rig.manager.module("walking")
    walking.start(0.03, 0, 0)
    assert walking.active
    rig.manager.stop_all()  # the lease ended
    for _ in range(300):
        out = rig.step(_frame(rig, 512, (512, 512, 512)))
        assert not out.goal
    assert not walking.running and not rig.manager.module("action").status()["playing"]
