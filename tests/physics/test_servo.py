"""One servo in physics: a step of its goal register at P 32 settles, and what it reports
(present position, speed, load) comes from the simulated joint."""

from __future__ import annotations

import math

import pytest

from robot_daemon.bus.tables import MX28
from robot_daemon.frames import Targets
from tests.fixtures.sim_rig import TICK_S, SimRig

PAN = 19


def test_head_pan_step_response_at_p32_settles() -> None:
    rig = SimRig(seed=3, physics="mujoco", vision_fps=0)
    goal = 0.6
    trace: list[tuple[float, float, float, float]] = []  # time, position, speed, load
    for _ in range(int(1.5 / TICK_S)):
        f = rig.frame()
        trace.append((rig.time, f.position[PAN], f.velocity[PAN], f.load[PAN]))
        rig.bus.write_targets(Targets(goal={PAN: goal}, gains={PAN: (32, 0, 0)}))
        rig.emulator.advance(TICK_S)
        rig.time += TICK_S
    assert rig.emulator.api.register(PAN, "P_GAIN") == 32
    peak = max(p for _, p, _, _ in trace)
    final = [p for t, p, _, _ in trace if t > 1.0]
    # Settled: within a degree of the goal for the last half second, without ringing.
    assert all(abs(p - goal) < math.radians(1.0) for p in final)
    assert peak < goal + math.radians(5.0)
    # On the way it ran (speed reported, up to the MX-28's ~55 rpm) under load; at rest, none.
    assert max(s for _, _, s, _ in trace) > 1.0
    assert max(s for _, _, s, _ in trace) < 55 * 2 * math.pi / 60 * 1.1
    assert max(abs(ld) for _, _, _, ld in trace) > 0.2
    assert abs(trace[-1][3]) < 0.1
    # The joint in MuJoCo is where the register says.
    joint = rig.world.data.joint("j_pan").qpos[0]
    raw = rig.emulator.api.register(PAN, "PRESENT_POSITION")
    assert abs(joint - (raw - 2048) * 2 * math.pi / 4096) < 0.002


def test_torque_off_leaves_the_joint_limp_and_the_load_zero() -> None:
    rig = SimRig(seed=3, physics="mujoco", vision_fps=0)
    # The right arm raised forward (shoulder pitch 1), then let go: it falls on gravity alone.
    for _ in range(100):
        rig.frame()
        rig.bus.write_targets(Targets(goal={1: 1.0}, gains={1: (32, 0, 0)}))
        rig.emulator.advance(TICK_S)
    rig.frame()
    rig.bus.set_torque([1], False)
    before = rig.world.data.joint("j_shoulder_r").qpos[0]
    assert abs(before - 1.0) < 0.05
    rig.emulator.advance(1.0)
    assert rig.emulator.api.register(1, "TORQUE_ENABLE") == 0
    assert rig.emulator.api.register(1, "PRESENT_LOAD") == 0
    moved = abs(rig.world.data.joint("j_shoulder_r").qpos[0] - before)
    assert moved > math.radians(5.0)


def test_low_voltage_weakens_the_servo() -> None:
    """Torque ∝ supply voltage: at 6 V a goal far from the pose saturates at half the 12 V
    torque (the load register reads the duty, so it stays near 100 %)."""
    forces = {}
    for volts in (12.0, 6.0):
        rig = SimRig(seed=3, physics="mujoco", vision_fps=0)
        rig.emulator.api.set_voltage(volts)
        rig.bus.write_targets(Targets(goal={PAN: 1.2}, gains={PAN: (32, 0, 0)}))
        rig.emulator.advance(0.004)
        forces[volts] = abs(float(rig.world.data.actuator("servo_19").force[0]))
        load = rig.emulator.api.register(PAN, "PRESENT_LOAD") & 0x3FF
        assert load > 900
    assert forces[6.0] == pytest.approx(forces[12.0] / 2, rel=0.05)
    assert MX28.TORQUE_LIMIT  # the torque limit register scales the same range


def test_moving_speed_register_paces_the_move() -> None:
    """A client that sets MOVING_SPEED (as pypot or the SDK may) gets a move at that speed."""
    rig = SimRig(seed=3, physics="mujoco", vision_fps=0)
    servo = rig.emulator.bus.servo(PAN)
    rad_s = 50 * 0.114 * 2 * math.pi / 60  # 50 units of 0.114 rpm ≈ 0.6 rad/s
    with rig.emulator.lock:
        assert servo.write(MX28.MOVING_SPEED.reg.address, (50).to_bytes(2, "little")) == 0
        goal = 2048 + 400  # ≈ 0.61 rad
        assert servo.write(MX28.GOAL_POSITION.reg.address, goal.to_bytes(2, "little")) == 0
    rig.emulator.advance(0.5)
    halfway = float(rig.world.data.joint("j_pan").qpos[0])
    assert halfway == pytest.approx(0.5 * rad_s, abs=0.05)
    rig.emulator.advance(1.0)
    assert abs(float(rig.world.data.joint("j_pan").qpos[0]) - 400 * 2 * math.pi / 4096) < 0.02
