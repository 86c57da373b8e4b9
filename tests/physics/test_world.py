"""The world ops against the physics world: same ops, same World message, real bodies."""

from __future__ import annotations

import math

import pytest

from robot_daemon.bus.tables import MX28, ErrorBit
from robot_daemon.emulator.control_service import run_op
from robot_daemon.frames import Targets
from robot_daemon.plant import world_ops
from schemas.messages import World, decode, encode
from tests.fixtures.sim_rig import TICK_S, SimRig


@pytest.fixture
def rig() -> SimRig:
    world_ops.install()
    r = SimRig(seed=4, physics="mujoco", vision_fps=0)
    r.emulator.world = r.world  # type: ignore[attr-defined]  # as the sim plugin does
    return r


def test_place_robot_stands_it_there_with_the_soles_on_the_ground(rig: SimRig) -> None:
    reply = run_op(rig.emulator, {"op": "place_robot", "x": 0.5, "y": -0.25, "yaw": 1.0})
    assert reply["robot"] == pytest.approx({"x": 0.5, "y": -0.25, "yaw": 1.0}, abs=0.03)
    d = rig.world.data
    soles = [float(d.site(s).xpos[2]) for s in ("l_sole", "r_sole")]
    assert min(soles) == pytest.approx(0.0, abs=1e-6)
    rig.run(1.0)
    snap = rig.world.snapshot()
    assert snap.fallen == "none"
    assert math.hypot(snap.robot["x"] - 0.5, snap.robot["y"] + 0.25) < 0.03  # no launch
    # The World message is the same type as the kinematic world's, and round-trips.
    assert isinstance(snap, World) and decode(encode(snap)) == snap


def test_ball_rolls_slows_and_stops_by_rolling_friction(rig: SimRig) -> None:
    run_op(rig.emulator, {"op": "place_ball", "x": 0.0, "y": 1.0, "vx": 1.0, "vy": 0.0})
    rig.emulator.advance(0.5)
    mid = rig.world.snapshot().ball
    assert 0.2 < mid["x"] < 0.5 and 0.3 < mid["vx"] < 1.0
    rig.emulator.advance(6.0)
    end = rig.world.snapshot().ball
    assert end["x"] > mid["x"] and abs(end["vx"]) < 0.02
    assert end["y"] == pytest.approx(1.0, abs=0.02)
    run_op(rig.emulator, {"op": "remove_ball"})
    assert rig.world.snapshot().ball == {} and rig.world.ball_distance() is None


def test_a_servo_held_at_its_torque_limit_overloads_and_shuts_down(rig: SimRig) -> None:
    """The right arm raised forward, its torque limit then cut below what holding it takes:
    the motor saturates, OVERLOAD rises after a second, and ALARM_SHUTDOWN zeroes its limit."""
    for _ in range(100):
        rig.frame()
        rig.bus.write_targets(Targets(goal={1: 1.0}, gains={1: (32, 0, 0)}))
        rig.emulator.advance(TICK_S)
    servo = rig.emulator.bus.servo(1)
    assert servo.table[MX28.ALARM_SHUTDOWN] & ErrorBit.OVERLOAD
    with rig.emulator.lock:
        servo.write(MX28.TORQUE_LIMIT.reg.address, (5).to_bytes(2, "little"))
    rig.emulator.advance(0.5)
    assert rig.emulator.api.register(1, "TORQUE_LIMIT") == 5  # not yet: held for < 1 s
    assert abs(servo.plant_torque or 0.0) == pytest.approx(5 / 1023 * 2.5, rel=0.05)
    rig.emulator.advance(1.0)
    # OVERLOAD shut it down: the MX-28 zeroes TORQUE_LIMIT (TORQUE_ENABLE still reads 1)
    assert rig.emulator.api.register(1, "TORQUE_LIMIT") == 0
    assert servo.plant_torque == 0.0  # limp


def test_ball_state_read_directly_is_the_ball_now(rig: SimRig) -> None:
    """Readers such as ball play and the benchmarks read ``world.ball.state`` without asking for
    a snapshot first: it must follow the rolling ball, not stay where it was placed."""
    run_op(rig.emulator, {"op": "place_ball", "x": 0.0, "y": 1.0, "vx": 1.0, "vy": 0.0})
    rig.emulator.advance(0.5)
    b = rig.world.ball.state
    q = rig.world.data.qpos[rig.world._ball_q : rig.world._ball_q + 2]
    assert b is not None and b.x > 0.2 and 0.3 < b.vx < 1.0
    assert (b.x, b.y) == pytest.approx((float(q[0]), float(q[1])))
