"""The CM-730's IMU convention, pinned: the real board's register signs (Webots' DARwIn-OP
model and its real-robot wrapper, which hands the registers to the unmodified ROBOTIS gait):
gyro X counts the rate about −forward, gyro Y about −left, gyro Z about +up; accel X the
specific force along −left, accel Y along +forward, accel Z along +up. The daemon reads them
back to robot axes (x forward, y left, z up) through the same table.

Both plants must mean the same physical thing: the kinematic world and MuJoCo, pitched forward
and rolled to the right, give the same register signs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robot_daemon.bus.tables import CM730
from robot_daemon.emulator.emulator import Emulator
from robot_daemon.frames import Targets
from robot_daemon.plant.physics.mujoco_world import MujocoWorld
from robot_daemon.plant.world import SimWorld
from schemas.units import IMU_CENTER
from tests.fixtures.sim_rig import SimRig

CM = 200


def _registers(emu: Emulator) -> dict[str, int]:
    return {
        name: emu.api.register(CM, name)
        for name in ("GYRO_X", "GYRO_Y", "GYRO_Z", "ACCEL_X", "ACCEL_Y", "ACCEL_Z")
    }


def test_the_table_is_the_real_boards() -> None:
    from robot_daemon.bus.tables import IMU_ACCEL_AXES, IMU_GYRO_AXES

    assert IMU_GYRO_AXES == ((CM730.GYRO_X, -1), (CM730.GYRO_Y, -1), (CM730.GYRO_Z, 1))
    assert IMU_ACCEL_AXES == ((CM730.ACCEL_Y, 1), (CM730.ACCEL_X, -1), (CM730.ACCEL_Z, 1))


def _mujoco_tipped(axis: int, rate: float) -> dict[str, int]:
    """Registers with the MuJoCo torso turning at ``rate`` about robot ``axis``, tilted 30° by
    that rotation, held (no acceleration: the sensors of inverse dynamics at qacc = 0)."""
    emu = Emulator(realtime=False, wire_timing=False, imu_noise=0.0, seed=1)
    world = MujocoWorld()
    world.attach(emu)
    d, m = world.data, world.model
    q = world._root_q
    half = math.radians(30.0) / 2
    quat = [math.cos(half), 0.0, 0.0, 0.0]
    quat[1 + axis] = math.sin(half)
    d.qpos[q + 3 : q + 7] = quat
    d.qpos[q + 2] = 1.0  # clear of the floor
    d.qvel[:] = 0.0
    d.qvel[world._root_d + 3 + axis] = rate  # body-frame angular velocity
    d.qacc[:] = 0.0
    world.mj.mj_inverse(m, d)
    world._report(emu, 0.0, np.zeros(20, dtype=bool))
    return _registers(emu)


def _kinematic_pitched_forward() -> dict[str, int]:
    """The kinematic robot tipping forward on its ankles (both ankle pitches, through the bus),
    read mid-motion."""
    rig = SimRig(seed=1, physics="kinematic", vision_fps=1.0)
    assert isinstance(rig.world, SimWorld)
    for k in range(1, 16):
        lean = 0.02 * k  # ankle pitch servo angles that tip the body forward over the feet
        rig.frame()
        rig.bus.write_targets(Targets(goal={15: lean, 16: -lean}))
        rig.emulator.advance(0.008)
    return _registers(rig.emulator)


def test_pitching_forward_counts_gyro_y_down_and_accel_y_down_in_both_plants() -> None:
    phys = _mujoco_tipped(axis=1, rate=1.0)  # about +left: nose down
    assert phys["GYRO_Y"] < IMU_CENTER - 30
    assert phys["ACCEL_Y"] < IMU_CENTER - 30  # gravity pulls along −forward of a tipped body
    assert abs(phys["GYRO_X"] - IMU_CENTER) < 3 and abs(phys["ACCEL_X"] - IMU_CENTER) < 3
    kin = _kinematic_pitched_forward()
    assert kin["GYRO_Y"] < IMU_CENTER - 5
    assert kin["ACCEL_Y"] < IMU_CENTER - 5


def test_rolling_right_counts_gyro_x_down_and_accel_x_down() -> None:
    phys = _mujoco_tipped(axis=0, rate=1.0)  # about +forward: right side down
    assert phys["GYRO_X"] < IMU_CENTER - 30
    assert phys["ACCEL_X"] < IMU_CENTER - 30  # the left side up: gravity along +left
    assert abs(phys["GYRO_Y"] - IMU_CENTER) < 3


def test_turning_left_counts_gyro_z_up_and_upright_accel_z_is_plus_one_g() -> None:
    phys = _mujoco_tipped(axis=2, rate=1.0)
    assert phys["GYRO_Z"] > IMU_CENTER + 30
    assert phys["ACCEL_Z"] == pytest.approx(IMU_CENTER + 128, abs=3)  # +1 g at 8 g / 1023
