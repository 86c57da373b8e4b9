"""The plant stands the robot: lock-step with the emulator's clock, the daemon's bus code on
top (SimRig), nothing faked between the registers and the bodies."""

from __future__ import annotations

import math

import pytest

from tests.fixtures.sim_rig import SimRig


@pytest.fixture(scope="module")
def rig() -> SimRig:
    return SimRig(seed=5, physics="mujoco", vision_fps=0)


def test_stands_ten_seconds_in_the_walk_ready_pose(rig: SimRig) -> None:
    walking = rig.manager.module("walking")
    walking.start()  # blends into the walk-ready stance and marks time there
    rig.run(1.0)
    walking.stop()
    rig.run(1.0)
    x0, y0, _ = rig.world.robot_pose()
    rig.run(10.0)
    x, y, _ = rig.world.robot_pose()
    snap = rig.world.snapshot()
    assert snap.fallen == "none" and rig.world.falls == 0
    assert math.hypot(x - x0, y - y0) < 0.05  # it stood, it did not wander
    torso_z = float(rig.world.data.body("torso").xpos[2])
    assert 0.2 < torso_z < 0.3  # on its legs, the soles on the ground
    assert snap.sim_time == pytest.approx(rig.time, abs=0.002)  # lock-step with the rig
