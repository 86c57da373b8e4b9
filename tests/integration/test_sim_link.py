"""The bus's two transports carry the same protocol: the simulated rig (in-process link) reads
exactly the frame the daemon reads over the pty, and on the link's simulated wire a reply that
never comes costs its own bounded wait, not a tick."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest

from config.loader import load_all
from robot_daemon.bus.packet import PACKET_OVERHEAD
from robot_daemon.bus.robot_bus import RobotBus
from robot_daemon.bus.tables import (
    CM730_BULK_LENGTH,
    SERVO_BULK_LENGTH,
    SERVO_IDS,
)
from robot_daemon.frames import JointFrame
from tests.fixtures.sim_rig import TICK_S, SimRig

FRAME_FIELDS = (
    "position",
    "velocity",
    "load",
    "online",
    "torque_enabled",
    "gyro",
    "accel",
    "gyro_raw",
    "accel_raw",
)


def odd_settings(**bus: Any) -> dict[str, Any]:
    """Settings where a shortcut around the daemon's bus code would show: a reversed, offset
    joint and a gyro scale that is not the default."""
    s = copy.deepcopy(load_all())
    s["robot"]["joints"]["r_knee"].update(offset_deg=3.0, direction=-1)
    s["imu"]["gyro_full_scale_dps"] = 1600.0
    s["bus"] = {**s.get("bus", {}), **bus}
    return s


def assert_same_frame(a: JointFrame, b: JointFrame) -> None:
    for name in FRAME_FIELDS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_the_rig_reads_the_frame_the_daemon_reads_over_the_pty() -> None:
    rig = SimRig(seed=5, settings=odd_settings())
    rig.run(0.3)  # servos settled, torque on, the knee where the standing pose put it
    emu = rig.emulator
    emu.api.set_body_motion(gyro_rad_s=(0.4, -0.25, 0.1), accel_ms2=(1.5, -2.0, 9.2))
    emu.api.set_external_load(4, 0.3)
    emu.start()  # the same emulator, now also on a pty
    try:
        events: list[Any] = []
        # A generous margin: the emulator answers from this very process.
        settings = odd_settings(power_on_delay_ms=0.0, reply_margin_ms=30.0)
        daemon = RobotBus(emu.port, rig.robot, settings, lambda *a, **k: events.append(a))
        daemon.open()
        try:
            daemon.power_on()
            assert sorted(daemon.scan()) == [*SERVO_IDS, 200]
            daemon.initial_read()
            daemon.read_sensors()
            over_pty = daemon.frame(rig.tick, rig.time, TICK_S)
        finally:
            daemon.close()
    finally:
        emu.stop()
    in_process = rig.frame()
    assert_same_frame(in_process, over_pty)
    # The frame is not trivially empty: the knee is reversed and offset, the body turns.
    knee = rig.robot.joint("r_knee").id
    assert in_process.position[knee] != pytest.approx(0.0, abs=0.05)
    assert in_process.gyro[0] == pytest.approx(0.4, abs=0.05)


def test_the_rig_clamps_goals_to_the_joint_limits_as_the_daemon_does() -> None:
    rig = SimRig(seed=2)
    knee = rig.robot.joint("r_knee")
    rig.bus.write_targets(rig.manager.step(rig.frame()))
    from robot_daemon.frames import Targets

    rig.bus.write_targets(Targets(goal={knee.id: knee.max_rad + 1.0}))
    assert rig.bus.counters.limit_clamps == 1
    goal = emu_goal(rig, knee.id)
    assert rig.bus.raw_to_joint(knee.id, goal) == pytest.approx(knee.max_rad, abs=0.002)


def emu_goal(rig: SimRig, jid: int) -> int:
    from robot_daemon.bus.tables import MX28

    return rig.emulator.api.register(jid, MX28.GOAL_POSITION.name)


def rig_without_slow_reads() -> SimRig:
    settings = load_all()
    # Every tick reads the same blocks, so two ticks' wire times compare.
    settings["daemon"] = {**settings.get("daemon", {}), "slow_reads_per_tick": 0}
    rig = SimRig(seed=4, settings=settings)
    rig.run(0.1)  # past the start's writes: the wire is free when a tick begins
    return rig


def bus_ms(rig: SimRig) -> float:
    """Time on the link's wire for one tick's bulk read."""
    start = rig.link.clock_ms
    rig.bus.read_sensors()
    return rig.link.clock_ms - start


def test_a_missing_reply_costs_its_own_wait_not_a_tick() -> None:
    rig = rig_without_slow_reads()
    bus, byte_ms = rig.bus, rig.link.tx_time_per_byte
    assert bus.dxl is not None
    clean = bus_ms(rig)
    # The wire floor: the instruction, then every reply (return delay 0 on the emulator).
    n = len(SERVO_IDS) + 1
    floor = byte_ms * (
        PACKET_OVERHEAD
        + 1
        + 3 * n
        + len(SERVO_IDS) * (SERVO_BULK_LENGTH + PACKET_OVERHEAD)
        + CM730_BULK_LENGTH
        + PACKET_OVERHEAD
    )
    assert clean == pytest.approx(floor)
    reply = byte_ms * (SERVO_BULK_LENGTH + PACKET_OVERHEAD)
    # On the real bus a servo that does not answer silences the ones after it (each waits for
    # the status packet before its own; the emulator models the chain): the tail is asked again
    # at once with the silent one last. The tick costs one wait, the retry's instruction and the
    # tail's replies again, and one more wait: bounded, under a tick, and only the silent servo
    # is blamed.
    rig.emulator.api.silence(7)
    tail = [j for j in SERVO_IDS if j > 7]
    wait = bus.dxl.budget.reply_ms(byte_ms, 7, SERVO_BULK_LENGTH + PACKET_OVERHEAD)
    assert wait == pytest.approx(reply + bus.reply_margin_ms)
    retry_tx = byte_ms * (PACKET_OVERHEAD + 1 + 3 * (len(tail) + 1))
    lossy = bus_ms(rig)
    assert clean < lossy <= clean + 2 * wait + retry_tx + len(tail) * reply + 1e-5
    assert lossy < TICK_S * 1000
    assert bus.counters.missing_replies == 1 and bus.counters.retries == 1
    assert [j for j in SERVO_IDS if bus.state.misses[j]] == [7]
    # The last one missing silences nobody: it is waited for once, bounded by its reply's wire
    # time + return delay + margin, and not asked again (nothing behind it needs the chain).
    rig.emulator.api.silence(7, False)
    rig.emulator.api.silence(20)
    lossy = bus_ms(rig)
    assert bus.counters.retries == 1
    expected = clean - reply + wait
    # The read that finds the tail missing looks when every reply should be in, so the waits
    # can start up to the missing reply's own wire time later.
    assert expected - 1e-5 <= lossy <= expected + reply + 1e-5
    # A fixed timeout (the SDK's 34 ms, the emulator's old 15 ms) would have cost a tick or two.
    assert lossy - clean < 4.0


def test_under_drops_and_corruption_each_pass_waits_at_most_once() -> None:
    rig = rig_without_slow_reads()
    bus, stats = rig.bus, rig.emulator.stats
    assert bus.dxl is not None
    rig.emulator.api.set_faults(drop=0.05, corrupt=0.01)
    byte_ms = rig.link.tx_time_per_byte
    floor = bus_ms(rig)  # the first tick happens to be clean with this seed
    wait = bus.dxl.budget.reply_ms(byte_ms, 1, CM730_BULK_LENGTH + PACKET_OVERHEAD)
    over = []
    for _ in range(500):
        before = stats["dropped"] + stats["corrupted"]
        took = bus_ms(rig)
        bad = stats["dropped"] + stats["corrupted"] - before
        rig.link.idle_until(rig.link.clock_ms + TICK_S * 1000)
        # At most one wait runs out in the bulk read and one in its retry of the missing tail,
        # whatever the number of bad replies; on the real chain a missing reply silences the
        # rest, so the retry may ask the whole tail again (at most every device).
        n = len(SERVO_IDS) + 1 if bad else 0
        retry = byte_ms * (PACKET_OVERHEAD + 1 + 3 * n + n * (CM730_BULK_LENGTH + 6))
        if took > floor + 2 * wait + retry + 1e-6:
            over.append((took, bad))
    faults = stats["dropped"] + stats["corrupted"]
    assert faults > 300  # the faults happened: ~6 % of ~21 replies a tick
    # Every retry was caused by a bad reply.
    assert 0 < bus.counters.retries <= faults
    assert over == []


def test_only_the_first_of_a_silent_tail_is_blamed() -> None:
    """On the real bus a silent device silences every one after it, and a late bus looks the
    same: the ones cut off are not counted against (and not sent offline)."""
    rig = rig_without_slow_reads()
    bus = rig.bus
    for dxl_id in (18, 19, 20):
        rig.emulator.api.silence(dxl_id)
    bus.read_sensors()
    assert bus.counters.retries == 1
    assert bus.counters.missing_replies == 3
    assert [int(bus.state.misses[j]) for j in (17, 18, 19, 20)] == [0, 1, 0, 0]
    # The retry's first answer shows the chain held: the one before it is blamed alone.
    for dxl_id in (18, 19, 20):
        rig.emulator.api.silence(dxl_id, False)
    rig.emulator.api.silence(10)
    bus.read_sensors()
    assert [int(bus.state.misses[j]) for j in (10, 18)] == [1, 0]
