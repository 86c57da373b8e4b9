"""The emulator through the real dynamixel-sdk over a real pseudo-terminal at 1 Mbps."""

from __future__ import annotations

import threading
import time

import pytest
from dynamixel_sdk import (
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    GroupBulkRead,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
)

from robot_daemon.bus.bulk_read import BulkRead
from robot_daemon.bus.packet import instruction_packet
from robot_daemon.bus.tables import (
    CM730,
    CM730_BULK_LENGTH,
    CM730_BULK_START,
    CM730_ID,
    CM730_MODEL,
    MX28,
    MX28_MODEL,
    SERVO_BULK_LENGTH,
    SERVO_BULK_START,
    SERVO_IDS,
    ErrorBit,
    Instruction,
)
from robot_daemon.emulator import Emulator
from schemas import units
from tests.fixtures.emulator import open_sdk, wait_until

SDK = tuple[PortHandler, PacketHandler]


def sensor_bulk_read(port: PortHandler, ph: PacketHandler) -> BulkRead:
    reader = BulkRead(port, ph)
    for dxl_id in SERVO_IDS:
        assert reader.addParam(dxl_id, SERVO_BULK_START, SERVO_BULK_LENGTH)
    assert reader.addParam(CM730_ID, CM730_BULK_START, CM730_BULK_LENGTH)
    return reader


def test_ping_finds_all_21_devices_with_their_model_numbers(dxl: SDK) -> None:
    port, ph = dxl
    models = {}
    for dxl_id in (CM730_ID, *SERVO_IDS):
        model, result, error = ph.ping(port, dxl_id)
        assert (result, error) == (COMM_SUCCESS, 0), dxl_id
        models[dxl_id] = model
    assert models[CM730_ID] == CM730_MODEL
    assert all(models[i] == MX28_MODEL for i in SERVO_IDS)
    assert ph.read1ByteTxRx(port, CM730_ID, CM730.FIRMWARE_VERSION.reg.address)[0] == 0x13
    assert ph.read2ByteTxRx(port, 5, MX28.CCW_ANGLE_LIMIT.reg.address)[0] == 4095
    assert ph.read1ByteTxRx(port, 5, MX28.P_GAIN.reg.address)[0] == 32


def test_servos_are_silent_until_dxl_power(emulator: Emulator) -> None:
    port, ph = open_sdk(emulator.port, power=False, emulator=emulator)
    try:
        assert ph.ping(port, CM730_ID)[1] == COMM_SUCCESS
        assert ph.ping(port, 1)[1] == COMM_RX_TIMEOUT
        assert ph.write1ByteTxRx(port, CM730_ID, CM730.DXL_POWER.reg.address, 1) == (0, 0)
        assert ph.ping(port, 1)[1] == COMM_SUCCESS
        assert ph.write1ByteTxRx(port, CM730_ID, CM730.DXL_POWER.reg.address, 0) == (0, 0)
        assert ph.ping(port, 20)[1] == COMM_RX_TIMEOUT
    finally:
        port.closePort()


def test_servos_answer_only_after_the_power_on_delay(emulator_factory) -> None:
    emu = emulator_factory(realtime=False, power_on_delay_s=0.3)
    port, ph = open_sdk(emu.port, emulator=emu)  # writes DXL_POWER = 1
    try:
        emu.advance(0.25)
        assert ph.ping(port, 3)[1] == COMM_RX_TIMEOUT
        emu.advance(0.05)
        assert ph.ping(port, 3)[1] == COMM_SUCCESS
    finally:
        port.closePort()


def test_bulk_read_of_20_servos_and_the_cm730_in_one_transaction(
    emulator: Emulator, dxl: SDK
) -> None:
    port, ph = dxl
    emulator.api.set_present_position(7, units.raw_to_rad(1000))
    reader = sensor_bulk_read(port, ph)
    before = emulator.stats["frames"]
    assert reader.txRxPacket() == COMM_SUCCESS
    assert emulator.stats["frames"] == before + 1  # one instruction packet on the wire
    assert emulator.received[-1].code == Instruction.BULK_READ
    assert reader.getData(7, MX28.PRESENT_POSITION.reg.address, 2) == 1000
    assert reader.getData(8, MX28.PRESENT_POSITION.reg.address, 2) == 2048
    assert reader.getData(CM730_ID, CM730.DXL_POWER.reg.address, 1) == 1
    accel_z = reader.getData(CM730_ID, CM730.ACCEL_Z.reg.address, 2)
    assert abs(units.accel_raw_to_ms2(accel_z) - units.GRAVITY) < 0.5  # upright: 1 g up
    assert abs(reader.getData(CM730_ID, CM730.ACCEL_Y.reg.address, 2) - 512) < 8
    result, data, errors = reader.read()
    assert result == COMM_SUCCESS
    assert list(data) == [*SERVO_IDS, CM730_ID]
    assert all(len(data[i]) == SERVO_BULK_LENGTH for i in SERVO_IDS)
    assert len(data[CM730_ID]) == CM730_BULK_LENGTH
    assert set(errors.values()) == {0}


def test_sdk_group_bulk_read_is_broken_on_protocol_1(dxl: SDK) -> None:
    """dynamixel-sdk 4.1.0 passes bulkReadTx an argument it does not take (see bulk_read.py).

    When this test fails, the SDK was fixed: BulkRead may become GroupBulkRead again.
    """
    port, ph = dxl
    reader = GroupBulkRead(port, ph)
    reader.addParam(1, SERVO_BULK_START, SERVO_BULK_LENGTH)
    with pytest.raises(TypeError, match="bulkReadTx"):
        reader.txRxPacket()


def test_sync_write_goals_converge_at_the_moving_speed(emulator_factory) -> None:
    emu = emulator_factory(realtime=False)
    port, ph = open_sdk(emu.port, emulator=emu)
    try:
        torque = GroupSyncWrite(port, ph, MX28.TORQUE_ENABLE.reg.address, 1)
        for dxl_id in (1, 2):
            torque.addParam(dxl_id, [1])
        assert torque.txPacket() == COMM_SUCCESS
        # ID 1 at the MX-28's maximum (moving speed 0), ID 2 limited to 100 units (11.4 rpm).
        assert ph.write2ByteTxRx(port, 2, MX28.MOVING_SPEED.reg.address, 100) == (0, 0)
        goals = GroupSyncWrite(port, ph, MX28.GOAL_POSITION.reg.address, 2)
        goals.addParam(1, [0xB8, 0x0B])  # 3000
        goals.addParam(2, [0x00, 0x04])  # 1024
        frames = emu.stats["frames"]
        assert goals.txPacket() == COMM_SUCCESS
        assert emu.wait_stat("frames", frames + 1)  # the sync write gets no reply
        assert emu.api.goal_positions()[1] == pytest.approx(units.raw_to_rad(3000))

        emu.advance(0.2)
        units_per_rpm_s = units.UNITS_PER_REV / 60.0
        fast = units.MX28_MAX_RPM * units_per_rpm_s * 0.2  # ~751 units
        slow = 100 * units.RPM_PER_SPEED_UNIT * units_per_rpm_s * 0.2  # ~156 units
        assert ph.read2ByteTxRx(port, 1, 36)[0] == pytest.approx(2048 + fast, abs=1)
        assert ph.read2ByteTxRx(port, 2, 36)[0] == pytest.approx(2048 - slow, abs=1)
        speed = units.signed_11bit(ph.read2ByteTxRx(port, 2, MX28.PRESENT_SPEED.reg.address)[0])
        assert speed == pytest.approx(-100, abs=1)  # CW: direction bit set
        assert ph.read1ByteTxRx(port, 1, MX28.MOVING.reg.address)[0] == 1

        emu.advance(0.5)
        assert ph.read2ByteTxRx(port, 1, 36)[0] == 3000  # arrived and holds
        assert ph.read2ByteTxRx(port, 1, MX28.PRESENT_SPEED.reg.address)[0] == 0
        assert ph.read1ByteTxRx(port, 1, MX28.MOVING.reg.address)[0] == 0
        assert ph.read2ByteTxRx(port, 3, 36)[0] == 2048  # torque off: stays where it is
    finally:
        port.closePort()


def test_torque_off_joint_stays_where_it_is(emulator_factory) -> None:
    emu = emulator_factory(realtime=False)
    port, ph = open_sdk(emu.port, emulator=emu)
    try:
        assert ph.write2ByteTxRx(port, 4, MX28.GOAL_POSITION.reg.address, 2500) == (0, 0)
        emu.advance(1.0)
        assert ph.read2ByteTxRx(port, 4, 36)[0] == 2048
        assert ph.read1ByteTxRx(port, 4, MX28.TORQUE_ENABLE.reg.address)[0] == 0
    finally:
        port.closePort()


def test_write_errors_set_the_documented_bits(dxl: SDK) -> None:
    port, ph = dxl
    present = MX28.PRESENT_POSITION.reg.address
    assert ph.write2ByteTxRx(port, 1, present, 100) == (COMM_SUCCESS, ErrorBit.RANGE)
    assert ph.write1ByteTxRx(port, 1, MX28.TORQUE_ENABLE.reg.address, 2) == (0, ErrorBit.RANGE)
    assert ph.write2ByteTxRx(port, 1, MX28.CCW_ANGLE_LIMIT.reg.address, 3000) == (0, 0)
    goal = MX28.GOAL_POSITION.reg.address
    assert ph.write2ByteTxRx(port, 1, goal, 3500) == (0, ErrorBit.ANGLE_LIMIT)
    assert ph.read2ByteTxRx(port, 1, goal) == (2048, 0, 0)  # refused, not clamped
    assert ph.write2ByteTxRx(port, CM730_ID, CM730.LED_HEAD.reg.address, 0x8000) == (0, 8)
    # The framework's sync-write block includes the reserved byte 29: accepted.
    assert ph.writeTxRx(port, 1, 26, 6, [0, 0, 32, 0, 0, 8]) == (0, 0)


def test_leds_and_buttons_read_back(emulator: Emulator, dxl: SDK) -> None:
    port, ph = dxl
    orange = units.rgb_to_color_word(255, 128, 0)
    assert ph.write2ByteTxRx(port, CM730_ID, CM730.LED_HEAD.reg.address, orange) == (0, 0)
    assert ph.write1ByteTxRx(port, CM730_ID, CM730.LED_PANEL.reg.address, 5) == (0, 0)
    assert ph.read2ByteTxRx(port, CM730_ID, CM730.LED_HEAD.reg.address)[0] == orange
    assert ph.read1ByteTxRx(port, CM730_ID, CM730.LED_PANEL.reg.address)[0] == 5
    emulator.api.press_button("start")
    assert ph.read1ByteTxRx(port, CM730_ID, CM730.BUTTON.reg.address)[0] == 0x02
    emulator.api.press_button("start", pressed=False)
    assert ph.read1ByteTxRx(port, CM730_ID, CM730.BUTTON.reg.address)[0] == 0


def test_imu_follows_body_motion(emulator: Emulator, dxl: SDK) -> None:
    port, ph = dxl
    emulator.api.set_body_motion(gyro_rad_s=(0.0, 1.0, 0.0), accel_ms2=(-units.GRAVITY, 0.0, 0.0))
    gyro_y = ph.read2ByteTxRx(port, CM730_ID, CM730.GYRO_Y.reg.address)[0]
    accel_y = ph.read2ByteTxRx(port, CM730_ID, CM730.ACCEL_Y.reg.address)[0]
    # Gyro Y counts the rate about −left (the real CM-730's sign, IMU_GYRO_AXES).
    assert units.gyro_raw_to_rad_s(gyro_y) == pytest.approx(-1.0, abs=0.05)
    assert accel_y < 390  # lying on its face: the framework's "fallen forward"


def test_dropped_and_delayed_replies_time_out_corrupt_ones_fail_the_checksum(
    emulator: Emulator, dxl: SDK
) -> None:
    port, ph = dxl
    emulator.api.set_faults(drop=1.0)
    assert ph.read2ByteTxRx(port, 1, 36)[1] == COMM_RX_TIMEOUT
    emulator.api.set_faults(drop=0.0, corrupt=1.0)
    assert ph.read2ByteTxRx(port, 1, 36)[1] == COMM_RX_CORRUPT
    assert ph.ping(port, 1)[1] == COMM_RX_CORRUPT  # checksum byte itself
    emulator.api.set_faults(corrupt=0.0, delay=1.0, delay_ms=1000)  # past the reply margin
    assert ph.read2ByteTxRx(port, 1, 36)[1] == COMM_RX_TIMEOUT
    emulator.api.set_faults(delay=0.0)
    assert ph.read2ByteTxRx(port, 1, 36) == (2048, COMM_SUCCESS, 0)
    assert emulator.stats["dropped"] == 1 and emulator.stats["delayed"] == 1
    assert emulator.stats["corrupted"] == 2


def test_a_silent_servo_times_out_and_fails_the_bulk_read(emulator: Emulator, dxl: SDK) -> None:
    port, ph = dxl
    emulator.api.silence(7)
    assert ph.ping(port, 7)[1] == COMM_RX_TIMEOUT
    assert ph.ping(port, 8)[1] == COMM_SUCCESS
    result, data, _ = sensor_bulk_read(port, ph).read()
    assert result == COMM_RX_TIMEOUT
    assert list(data) == [1, 2, 3, 4, 5, 6]  # what arrived before the silent one
    # It still obeys: a write without reply is executed.
    frames = emulator.stats["frames"]
    ph.write1ByteTxOnly(port, 7, MX28.LED.reg.address, 1)
    assert emulator.wait_stat("frames", frames + 1)  # taken while still silent
    emulator.api.silence(7, False)
    assert ph.read1ByteTxRx(port, 7, MX28.LED.reg.address) == (1, COMM_SUCCESS, 0)


def test_overheating_sets_the_alarm_and_shuts_torque_off(emulator: Emulator, dxl: SDK) -> None:
    port, ph = dxl
    limit = MX28.TORQUE_LIMIT.reg.address
    assert ph.write1ByteTxRx(port, 9, MX28.TORQUE_ENABLE.reg.address, 1) == (0, 0)
    emulator.api.overheat(9)
    temp, result, error = ph.read1ByteTxRx(port, 9, MX28.PRESENT_TEMPERATURE.reg.address)
    assert result == COMM_SUCCESS and error & ErrorBit.OVERHEATING
    assert temp > ph.read1ByteTxRx(port, 9, MX28.TEMPERATURE_LIMIT.reg.address)[0]
    # The MX-28's alarm shutdown zeroes TORQUE_LIMIT (TORQUE_ENABLE still reads 1): limp.
    assert ph.read2ByteTxRx(port, 9, limit)[0] == 0
    assert ph.read1ByteTxRx(port, 9, MX28.TORQUE_ENABLE.reg.address)[0] == 1
    # A re-arm is accepted but the alarm keeps the limit at 0 while it lasts.
    ph.write2ByteTxRx(port, 9, limit, 1023)
    assert ph.read2ByteTxRx(port, 9, limit)[0] == 0
    emulator.api.overheat(9, False)
    assert ph.write2ByteTxRx(port, 9, limit, 1023) == (0, 0)
    assert ph.read2ByteTxRx(port, 9, limit) == (1023, 0, 0)


def test_sustained_load_heats_a_servo_past_its_limit(emulator_factory) -> None:
    emu = emulator_factory(realtime=False, max_step_s=0.25)  # minutes of heating in few steps
    port, ph = open_sdk(emu.port, emulator=emu)
    try:
        ph.write1ByteTxRx(port, 11, MX28.TORQUE_ENABLE.reg.address, 1)
        emu.api.set_external_load(11, 0.9)
        emu.advance(30.0)
        warm = ph.read1ByteTxRx(port, 11, MX28.PRESENT_TEMPERATURE.reg.address)
        assert warm[1:] == (COMM_SUCCESS, 0) and 40 < warm[0] < 80
        for _ in range(600):  # until the alarm shuts torque off (about 40 s more)
            emu.advance(1.0)
            if not emu.api.register(11, "TORQUE_LIMIT"):
                break
        temp, result, error = ph.read1ByteTxRx(port, 11, MX28.PRESENT_TEMPERATURE.reg.address)
        assert result == COMM_SUCCESS and error & ErrorBit.OVERHEATING
        assert temp >= 80
        assert ph.read2ByteTxRx(port, 11, MX28.TORQUE_LIMIT.reg.address)[0] == 0
        emu.advance(300.0)  # unloaded, it cools down and the alarm clears
        assert ph.read1ByteTxRx(port, 11, MX28.PRESENT_TEMPERATURE.reg.address)[2] == 0
    finally:
        port.closePort()


def test_low_voltage_sets_the_input_voltage_bit(emulator: Emulator, dxl: SDK) -> None:
    port, ph = dxl
    emulator.api.set_voltage(5.5)
    assert ph.ping(port, 1)[2] & ErrorBit.INPUT_VOLTAGE
    assert ph.read1ByteTxRx(port, CM730_ID, CM730.VOLTAGE.reg.address)[0] == 55
    emulator.api.set_voltage(12.0)
    assert ph.ping(port, 1)[2] == 0


def test_bad_checksum_gets_the_checksum_bit_and_is_not_executed(
    emulator: Emulator, dxl: SDK
) -> None:
    port, _ = dxl
    packet = bytearray(instruction_packet(1, Instruction.WRITE, [25, 1]))
    packet[-1] ^= 0x55
    port.clearPort()
    port.writePort(bytes(packet))
    assert emulator.wait_stat("bad_checksums", 1)
    deadline = time.monotonic() + 5
    reply = b""
    while len(reply) < 6 and time.monotonic() < deadline:
        reply += port.readPort(6 - len(reply))
    assert reply[:5] == bytes([0xFF, 0xFF, 1, 2, ErrorBit.CHECKSUM])
    assert emulator.api.register(1, "LED") == 0


def test_reg_write_waits_for_action(dxl: SDK, emulator: Emulator) -> None:
    port, ph = dxl
    assert ph.regWriteTxRx(port, 3, MX28.LED.reg.address, 1, [1]) == (0, 0)
    assert ph.read1ByteTxRx(port, 3, MX28.LED.reg.address)[0] == 0
    assert ph.read1ByteTxRx(port, 3, MX28.REGISTERED.reg.address)[0] == 1
    assert ph.action(port, 3) == COMM_SUCCESS
    assert ph.read1ByteTxRx(port, 3, MX28.LED.reg.address)[0] == 1
    _, error = ph.writeTxRx(port, 3, 0, 0, [])  # a WRITE without data
    assert error == ErrorBit.INSTRUCTION


def test_status_return_level_zero_answers_only_ping(dxl: SDK) -> None:
    port, ph = dxl
    assert ph.write1ByteTxRx(port, 2, MX28.STATUS_RETURN_LEVEL.reg.address, 0) == (0, 0)
    assert ph.read1ByteTxRx(port, 2, MX28.LED.reg.address)[1] == COMM_RX_TIMEOUT
    assert ph.ping(port, 2)[1] == COMM_RX_TIMEOUT  # ping() reads the model after the PING
    ph.write1ByteTxOnly(port, 2, MX28.STATUS_RETURN_LEVEL.reg.address, 2)
    assert ph.ping(port, 2)[1] == COMM_SUCCESS


def test_wire_timed_bulk_read_is_not_faster_than_the_wire(emulator_factory) -> None:
    emu = emulator_factory(wire_timing=True)
    port, ph = open_sdk(emu.port, emulator=emu)
    try:
        reader = sensor_bulk_read(port, ph)
        instruction = 7 + 3 * len(reader.data_dict)
        replies = sum(6 + length for _, _, length in reader.data_dict.values())
        wire = units.wire_time_s(instruction + replies)
        for _ in range(3):
            start = time.perf_counter()
            assert reader.txRxPacket() == COMM_SUCCESS
            assert time.perf_counter() - start >= wire
    finally:
        port.closePort()


def test_realtime_physics_hooks_run_while_the_bus_is_idle(emulator: Emulator) -> None:
    steps: list[float] = []
    enough = threading.Event()

    def world(dt: float, emu: Emulator) -> None:
        steps.append(dt)
        emu.api.set_body_motion(gyro_rad_s=(0.0, 0.0, 0.3))
        if len(steps) >= 5:
            enough.set()

    emulator.add_physics_hook(world)
    assert enough.wait(10)
    emulator.remove_physics_hook(world)
    assert all(0 < dt <= emulator.settings.max_step_s + 1e-9 for dt in steps)
    gyro_z = emulator.api.register(CM730_ID, "GYRO_Z")
    assert units.gyro_raw_to_rad_s(gyro_z) == pytest.approx(0.3, abs=0.05)


def test_the_realtime_clock_moves_servos_without_advance(emulator: Emulator, dxl: SDK) -> None:
    port, ph = dxl
    assert ph.write1ByteTxRx(port, 19, MX28.TORQUE_ENABLE.reg.address, 1) == (0, 0)
    assert ph.write2ByteTxRx(port, 19, MX28.GOAL_POSITION.reg.address, 2248) == (0, 0)

    def arrived() -> bool:
        return ph.read2ByteTxRx(port, 19, MX28.PRESENT_POSITION.reg.address)[0] == 2248

    assert wait_until(arrived, timeout=10)
    assert emulator.sim_time > 0.05  # 200 units at 55 rpm take 53 ms of simulated time


def test_two_servos_with_one_id_both_obey_and_their_differing_replies_collide(
    emulator: Emulator, dxl: SDK
) -> None:
    port, ph = dxl
    with emulator.lock:
        emulator.bus.servo(8).set_position(1500)  # the two stand at different angles
        emulator.bus.set_id(8, 7)  # servo 8 replaced with ID 7 by mistake
    assert ph.ping(port, 8)[1] == COMM_RX_TIMEOUT
    model, result, error = ph.ping(port, 7)  # the same packet from both: it passes
    assert (model, result, error) == (MX28_MODEL, COMM_SUCCESS, 0)
    assert ph.read2ByteTxRx(port, 7, MX28.MODEL_NUMBER.reg.address)[1] == COMM_SUCCESS
    assert ph.read2ByteTxRx(port, 7, MX28.PRESENT_POSITION.reg.address)[1] == COMM_RX_CORRUPT
    # Both obey a write to the ID: the goal reaches the wrong joint too.
    assert ph.write2ByteTxRx(port, 7, MX28.GOAL_POSITION.reg.address, 1800)[0] == COMM_SUCCESS
    emulator.wait_quiet()
    assert emulator.bus.servo(7).table[MX28.GOAL_POSITION] == 1800
    assert emulator.bus.servo(8).table[MX28.GOAL_POSITION] == 1800
    # In a bulk read the garbled packet is the last: the next device waits for it in vain.
    result, data, _ = sensor_bulk_read(port, ph).read()
    assert result != COMM_SUCCESS
    assert 9 not in data
