"""The `push` op in physics: a shove on the torso knocks the robot over the way it was pushed,
and the daemon's fall detector (motion/fall.py, on the CM-730's accelerometer registers) says
the same direction as the world."""

from __future__ import annotations

import pytest

from robot_daemon.emulator.control_service import run_op
from robot_daemon.plant import world_ops
from tests.fixtures.sim_rig import SimRig


@pytest.fixture(autouse=True)
def _world_ops() -> None:
    world_ops.install()  # what `darwin sim` does when it attaches a world


@pytest.mark.parametrize(
    ("fx", "direction"), [(-40.0, "backward"), (40.0, "forward")], ids=["back", "front"]
)
def test_a_push_knocks_the_robot_over_and_the_detector_agrees(fx: float, direction: str) -> None:
    rig = SimRig(seed=1, physics="mujoco", vision_fps=0)
    rig.emulator.world = rig.world  # type: ignore[attr-defined]  # as the sim plugin does
    assert rig.calibrated()  # the detector watches once the gyro centre is measured
    rig.run(0.7)  # and settled: pushed at once, the detector read the landing as backward
    reply = run_op(rig.emulator, {"op": "push", "fx": fx, "fy": 0.0, "duration": 0.2})
    assert reply["impulse"] == pytest.approx([fx * 0.2, 0.0, 0.0])
    fall = rig.manager.module("fall")
    called = []  # the detector's states as the robot goes over, in order
    for _ in range(20):
        rig.run(0.1)
        if not called or called[-1] != fall.state:
            called.append(fall.state)
    assert rig.world.snapshot().fallen == direction
    assert rig.world.falls == 1
    # Its first call is the fall, in the plant's direction (lying still with no get-up page, a
    # robot propped on an arm can later read as upright again to the accelerometer window).
    assert [s for s in called if s != "upright"][:1] == [f"fallen_{direction}"], called
    assert fall.falls == 1


def test_push_arguments_are_checked() -> None:
    rig = SimRig(seed=1, physics="mujoco", vision_fps=0)
    rig.emulator.world = rig.world  # type: ignore[attr-defined]
    for bad, word in (
        ({"fx": 1e6, "fy": 0.0}, "fx"),
        ({"fx": 1.0}, "fy"),
        ({"fx": 1.0, "fy": float("nan")}, "fy"),
        ({"fx": 1.0, "fy": 0.0, "duration": 0.0}, "duration"),
    ):
        with pytest.raises(Exception, match=word):
            run_op(rig.emulator, {"op": "push", **bad})
    assert rig.world.pushes == 0
