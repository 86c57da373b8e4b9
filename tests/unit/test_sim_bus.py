"""The simulated bus and devices without a pty: frames in, status packets out."""

from __future__ import annotations

import numpy as np
import pytest

from robot_daemon.bus.packet import Packet, PacketParser, instruction_packet
from robot_daemon.bus.tables import CM730_ID, MX28, ErrorBit, Instruction
from robot_daemon.emulator import Emulator, EmulatorSettings
from robot_daemon.emulator.servo_chain import Bus
from schemas import units


def make_bus(**kw) -> Bus:
    bus = Bus(np.random.default_rng(1), power_on_delay_s=0.0, **kw)
    bus.cm730.write(24, b"\x01")
    return bus


def ask(bus: Bus, dxl_id: int, inst: int, params: bytes | list[int] = b"") -> list[Packet]:
    """Send one instruction; the status packets that come back, parsed."""
    replies = bus.handle(Packet(dxl_id, inst, bytes(params)))
    parser = PacketParser()
    return [f for r in replies for f in parser.feed(r.packet)]


def test_bulk_read_answers_in_the_listed_order() -> None:
    bus = make_bus()
    params = [0, 2, 20, 36, 1, CM730_ID, 24, 2, 1, 36]
    replies = ask(bus, 254, Instruction.BULK_READ, params)
    assert [r.id for r in replies] == [20, CM730_ID, 1]
    assert replies[0].params == (2048).to_bytes(2, "little")
    assert replies[1].params == b"\x01"


@pytest.mark.parametrize("quiet", ["absent", "silent", "late CM-730"])
def test_a_device_that_does_not_answer_mid_chain_silences_the_rest_of_the_bulk_read(
    quiet: str,
) -> None:
    """Each device answers after the status packet of the one listed before it (a daisy
    chain): when that packet never comes, nobody after it answers this bulk read."""
    bus = make_bus()
    middle = {"absent": 99, "silent": 7, "late CM-730": CM730_ID}[quiet]
    if quiet == "silent":
        bus.silent.add(7)
    if quiet == "late CM-730":
        bus.cm730_late_reads = 1
    params = [0, 2, 20, 36, 1, middle, 24, 2, 1, 36]
    assert [r.id for r in ask(bus, 254, Instruction.BULK_READ, params)] == [20]
    if quiet != "absent":
        bus.silent.clear()  # silent again, or (late) answering from the next read on
        expected = [20, middle, 1]
        assert [r.id for r in ask(bus, 254, Instruction.BULK_READ, params)] == expected


def test_sync_write_applies_complete_blocks_only() -> None:
    bus = make_bus()
    params = [MX28.GOAL_POSITION.reg.address, 2, 1, 0x00, 0x08, 2, 0x10, 0x08, 3, 0x20]
    assert ask(bus, 254, Instruction.SYNC_WRITE, params) == []
    assert bus.servo(1).table[MX28.GOAL_POSITION] == 0x800
    assert bus.servo(2).table[MX28.GOAL_POSITION] == 0x810
    assert bus.servo(3).table[MX28.GOAL_POSITION] == 2048  # its block was cut short


def test_action_without_reg_write_is_an_instruction_error() -> None:
    bus = make_bus()
    assert ask(bus, 5, Instruction.ACTION)[0].code == ErrorBit.INSTRUCTION
    assert ask(bus, 5, 0x77)[0].code == ErrorBit.INSTRUCTION  # unknown instruction
    assert ask(bus, 5, Instruction.READ, [36])[0].code == ErrorBit.INSTRUCTION


def test_broadcast_reg_write_and_action() -> None:
    bus = make_bus()
    assert ask(bus, 254, Instruction.REG_WRITE, [MX28.LED.reg.address, 1]) == []
    assert bus.servo(4).table[MX28.LED] == 0 and bus.servo(4).table[MX28.REGISTERED] == 1
    assert ask(bus, 254, Instruction.ACTION) == []
    assert all(s.table[MX28.LED] == 1 for s in bus.servos.values())


def test_reset_restores_defaults_but_keeps_the_id() -> None:
    bus = make_bus()
    ask(bus, 6, Instruction.WRITE, [MX28.P_GAIN.reg.address, 80])
    assert ask(bus, 6, Instruction.RESET)[0].code == 0
    assert bus.servo(6).table[MX28.P_GAIN] == 32 and bus.servo(6).id == 6


def test_an_id_write_readdresses_the_servo() -> None:
    bus = make_bus()
    # The status packet already carries the new ID, as the firmware builds it after the write.
    assert ask(bus, 12, Instruction.WRITE, [MX28.ID.reg.address, 42])[0].id == 42
    assert ask(bus, 12, Instruction.PING) == []
    assert ask(bus, 42, Instruction.PING)[0].id == 42


def test_reads_past_the_table_end_and_locked_eeprom() -> None:
    bus = make_bus()
    reply = ask(bus, 1, Instruction.READ, [70, 10])[0]
    assert reply.code == ErrorBit.RANGE and len(reply.params) == 10  # zero-padded
    ask(bus, 1, Instruction.WRITE, [MX28.LOCK.reg.address, 1])
    reply = ask(bus, 1, Instruction.WRITE, [MX28.MAX_TORQUE.reg.address, 0, 2])[0]
    assert reply.code == ErrorBit.RANGE
    assert bus.servo(1).table[MX28.MAX_TORQUE] == 1023


def test_power_cut_silences_servos_and_power_up_restores_their_ram() -> None:
    bus = make_bus()
    ask(bus, 1, Instruction.WRITE, [MX28.TORQUE_ENABLE.reg.address, 1])
    bus.servo(1).set_position(3000)
    ask(bus, CM730_ID, Instruction.WRITE, [24, 0])
    assert ask(bus, 1, Instruction.PING) == []
    ask(bus, CM730_ID, Instruction.WRITE, [24, 1])
    t = bus.servo(1).table
    state = (t[MX28.TORQUE_ENABLE], t[MX28.GOAL_POSITION], t[MX28.PRESENT_POSITION])
    assert state == (0, 3000, 3000)


def test_physics_hooks_see_each_step_and_feed_the_imu() -> None:
    emu = Emulator(EmulatorSettings(seed=3, realtime=False, imu_noise=0.0, max_step_s=0.01))
    steps: list[float] = []

    def world(dt: float, e: Emulator) -> None:
        steps.append(dt)
        assert set(e.api.present_positions()) == set(range(1, 21))
        e.api.set_body_motion(gyro_rad_s=(0.5, 0.0, 0.0), accel_ms2=(0.0, 0.0, units.GRAVITY))

    emu.add_physics_hook(world)
    emu.advance(0.025)
    assert steps == pytest.approx([0.01, 0.01, 0.005])
    assert emu.sim_time == pytest.approx(0.025)
    # The CM-730 counts the rate about −forward on gyro X (IMU_GYRO_AXES, the real board's sign).
    gyro_x = units.gyro_raw_to_rad_s(emu.api.register(CM730_ID, "GYRO_X"))
    assert gyro_x == pytest.approx(-0.5, 0.02)
    assert emu.api.register(CM730_ID, "ACCEL_Z") == units.ms2_to_accel_raw(units.GRAVITY)
    with pytest.raises(ValueError, match="3 values"):
        emu.api.set_body_motion(gyro_rad_s=(1.0, 2.0))
    with pytest.raises(ValueError, match="time only goes forward"):
        emu.advance(-1)


def test_the_same_seed_gives_the_same_noise_and_faults() -> None:
    def run(seed: int) -> list[int]:
        emu = Emulator(EmulatorSettings(seed=seed, realtime=False, corrupt=0.5))
        out = []
        for _ in range(20):
            out.append(emu.api.register(CM730_ID, "GYRO_Y"))
            out.append(int(emu.faults.apply(emu.rng, instruction_packet(1, 1))[0] is not None))
        return out

    assert run(7) == run(7)
    assert run(7) != run(8)


def test_fault_settings_are_checked() -> None:
    emu = Emulator(EmulatorSettings(seed=1, realtime=False))
    with pytest.raises(ValueError, match=r"corrupt=1\.5"):
        emu.api.set_faults(corrupt=1.5)
    assert emu.api.fault_state()["corrupt"] == 0.0  # unchanged after a refused change
    with pytest.raises(KeyError, match="no servo with ID 33"):
        emu.api.overheat(33)
    with pytest.raises(ValueError, match="unknown button"):
        emu.api.press_button("reset")
