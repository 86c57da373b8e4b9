"""Servos as a first session finds them (issue 25): RAM left by a previous program, old
firmware, loaded joints that stand below their goal, and soft arms while walking."""

from __future__ import annotations

from collections.abc import Callable

from config.loader import load_all, load_robot
from robot_daemon.bus.robot_bus import RobotBus
from robot_daemon.bus.tables import MX28
from robot_daemon.emulator import Emulator
from robot_daemon.motion.setup import build_manager
from tests.unit.motion_rig import PerfectServos
from tests.unit.test_bus_robot import make_bus

KNEE = 13


def started(emulator: Emulator, **bus: object) -> tuple[RobotBus, list]:
    rb, events = make_bus(emulator.port, **bus)
    rb.power_on()
    rb.scan()
    rb.initial_read()
    rb.read_registers(KNEE, 0, 1)  # answered once the emulator has taken the writes before
    return rb, events


def test_leftover_moving_speed_and_torque_limit_are_reset_at_start(
    emulator_factory: Callable[..., Emulator],
) -> None:
    emu = emulator_factory(leftover_ram_ids=[3])
    emu.bus.servo(3).table[MX28.MAX_TORQUE] = 800  # EEPROM: this servo's own maximum
    rb, _ = started(emu)
    try:
        rb.read_registers(3, 0, 1)  # answered once the emulator has taken the writes before
        servo = emu.bus.servo(3).table
        assert servo[MX28.MOVING_SPEED] == 0
        assert servo[MX28.TORQUE_LIMIT] == 800
        assert emu.bus.servo(4).table[MX28.TORQUE_LIMIT] == 1023
    finally:
        rb.close()


def test_a_servo_with_old_firmware_is_refused_and_stays_offline(
    emulator_factory: Callable[..., Emulator],
) -> None:
    emu = emulator_factory(old_firmware_ids=[7])
    rb, _ = started(emu, probe_offline_every=1)
    try:
        rb.read_registers(8, 0, 1)  # answered once the emulator has taken the writes before
        line = next(w for w in rb.warnings if "servo 7" in w)
        assert "firmware 26" in line and "27 (0x1B)" in line
        assert not emu.bus.servo(7).table[MX28.TORQUE_ENABLE]
        assert emu.bus.servo(8).table[MX28.TORQUE_ENABLE]
        for _ in range(5):  # probes of offline servos do not bring it back
            rb.read_sensors()
        assert not rb.state.online[7]
    finally:
        rb.close()


def test_a_loaded_joint_keeps_its_goal_through_restart_halt_and_torque_on(
    emulator_factory: Callable[..., Emulator],
) -> None:
    emu = emulator_factory(sag_units=64.0, realtime=False)
    rb, _ = started(emu)
    knee = emu.bus.servo(KNEE)
    goal = knee.table[MX28.GOAL_POSITION]
    emu.api.set_external_load(KNEE, 0.5)
    emu.advance(1.0)
    assert knee.table[MX28.PRESENT_POSITION] == goal - 32  # P = 32 stands off under load
    rb.close()
    rb, _ = started(emu)  # the daemon restarts with torque still on
    try:
        assert knee.table[MX28.GOAL_POSITION] == goal
        rb.set_torque([KNEE], True)  # already on: nothing re-commanded
        assert knee.table[MX28.GOAL_POSITION] == goal
        manager = build_manager(load_robot(), load_all())
        rb.read_sensors()
        frame = rb.frame(1, 0.0, 0.008)
        manager.step(frame)
        manager.halt()
        rb.write_targets(manager.step(frame))
        rb.read_registers(KNEE, MX28.GOAL_POSITION.reg.address, 2)  # after the sync write
        assert knee.table[MX28.GOAL_POSITION] == goal
        emu.advance(1.0)
        assert knee.table[MX28.PRESENT_POSITION] == goal - 32  # not sinking further
    finally:
        rb.close()


def test_walking_softens_the_arms_and_the_configured_gains_come_back_after() -> None:
    robot = load_robot()
    rig = PerfectServos(build_manager(robot, load_all()))
    walking = rig.manager.module("walking")
    walking.start(0.03, 0, 0)
    for _ in range(400):  # the walk-ready page plays first
        out = rig.step()
        if rig.manager.owned_by("walking"):
            break
    assert out.gains[1] == (8, 0, 0) and out.gains[2] == (8, 0, 0)
    walking.stop()
    for _ in range(1000):
        out = rig.step()
        if not rig.manager.owned_by("walking"):
            break
    # The tick walking lets go: the arm's last goal again, with no module's gains (the
    # configured P is written).
    assert 1 in out.goal and 1 not in out.gains


def test_walking_starts_from_the_walk_ready_page() -> None:
    rig = PerfectServos(build_manager(load_robot(), load_all()))
    manager = rig.manager
    for _ in range(100):  # the gyro centre is measured first
        rig.step()
    manager.module("head").track(0.1, 0.0)
    rig.step()
    manager.module("walking").start(0.03, 0, 0)
    rig.step()
    action = manager.module("action").status()
    assert action["playing"] and action["page"] == 9
    assert not manager.owned_by("walking")
    assert manager.owner(19) == "head"  # the head keeps tracking
    for _ in range(400):
        rig.step()
        if manager.owned_by("walking"):
            break
    assert not manager.module("action").status()["playing"]
    assert manager.owned_by("walking") == set(range(1, 19))  # the arms 1-6 and the legs
