"""The project's gait (config/walking.toml, balance on) walks the MuJoCo robot: the daemon's
motion manager and bus code through the in-process link, lock-step with the plant (SimRig).

Distances are measured in the robot's own frame at the start; the heading is unwrapped tick by
tick, so a turn of more than half a revolution counts in full."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import pytest

from tests.fixtures.sim_rig import SimRig

WALK_S = 10.0


@dataclass
class Walked:
    forward: float  # m along the start heading
    left: float  # m to the left of it
    turned: float  # degrees, counter-clockwise positive
    falls: int


def walk(x: float, y: float, turn: float, settings: dict[str, Any] | None = None) -> Walked:
    """``settings``: another merged config (tests/learn/test_fast_model.py: the fast model)."""
    rig = SimRig(seed=2, physics="mujoco", vision_fps=0, settings=settings)
    walking = rig.manager.module("walking")
    walking.start()  # into the walk-ready stance, marking time
    rig.run(1.0)
    x0, y0, yaw0 = rig.world.robot_pose()
    yaw, turned = yaw0, 0.0
    walking.set_speed(x, y, turn)
    end = rig.time + WALK_S
    while rig.time < end - 1e-9:
        rig.step()
        heading = rig.world.robot_pose()[2]
        turned += math.remainder(heading - yaw, 2 * math.pi)
        yaw = heading
    x1, y1, _ = rig.world.robot_pose()
    c, s = math.cos(yaw0), math.sin(yaw0)
    dx, dy = x1 - x0, y1 - y0
    result = Walked(c * dx + s * dy, -s * dx + c * dy, math.degrees(turned), rig.world.falls)
    print(f"walk x={x} y={y} turn={turn} for {WALK_S} s: {result}")
    return result


def test_forward_one_metre_in_ten_seconds_straight() -> None:
    w = walk(0.1, 0.0, 0.0)
    assert w.falls == 0
    assert 0.8 <= w.forward <= 1.2
    assert abs(w.turned) < 15.0


def test_backward_goes_backward() -> None:
    w = walk(-0.1, 0.0, 0.0)
    assert w.falls == 0
    assert w.forward < -0.5
    assert abs(w.left) < abs(w.forward) / 2


@pytest.mark.parametrize("side", [1.0, -1.0], ids=["left", "right"])
def test_sideways_goes_the_commanded_side(side: float) -> None:
    w = walk(0.0, 0.05 * side, 0.0)
    assert w.falls == 0
    assert w.left * side > 0.2
    assert abs(w.forward) < w.left * side


@pytest.mark.parametrize("side", [1.0, -1.0], ids=["left", "right"])
def test_turning_in_place_turns_the_commanded_way(side: float) -> None:
    w = walk(0.0, 0.0, 0.5 * side)
    assert w.falls == 0
    assert w.turned * side > 90.0  # commanded 286° in 10 s
    assert math.hypot(w.forward, w.left) < 0.3  # in place, not walking off


def test_with_the_opposite_gyro_signs_the_balance_feedback_throws_it_over(monkeypatch) -> None:
    """The evidence for the register signs: the framework's balance law with the gyro X/Y
    counts growing the other way (the project's old map) is positive feedback."""
    from robot_daemon.bus import state
    from robot_daemon.bus.tables import CM730
    from robot_daemon.emulator import devices

    wrong = ((CM730.GYRO_X, 1), (CM730.GYRO_Y, 1), (CM730.GYRO_Z, 1))
    monkeypatch.setattr(devices, "IMU_GYRO_AXES", wrong)
    monkeypatch.setattr(state, "IMU_GYRO_AXES", wrong)
    rig = SimRig(seed=2, physics="mujoco", vision_fps=0)
    rig.manager.module("walking").start()
    rig.run(5.0)
    assert rig.world.falls >= 1
