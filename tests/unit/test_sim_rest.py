"""A servo at rest skips its step (``Servo._rest_key``), and a bulk read of a device whose
read changes nothing gives its last reply again (``Bus.reuse_replies``): neither may ever change
what the bus reads. Nor may what a servo finds once and uses twice: whether its motor drives
and its load, found once a step (again after an alarm shutdown), and the alarm bits a write's
status packet carries, found by the shutdown check before the shutdown. Two emulators live the
same seeded random life (goals, torque, speed and torque limits, loads, heat, supply voltage,
writes of any RAM register, steps of any length); one always runs the whole step and finds each
of these afresh where it is used (or builds every reply). After every step every servo's
control table and state are the same (and so is every bulk read's answer, and every write's
error bits)."""

from __future__ import annotations

import random
from collections.abc import Callable

import pytest

from robot_daemon.bus.packet import Packet
from robot_daemon.bus.tables import BROADCAST_ID, MX28, Instruction
from robot_daemon.emulator.devices import Servo
from robot_daemon.emulator.emulator import Emulator
from robot_daemon.emulator.settings import EmulatorSettings


def _state(emulator: Emulator) -> list[tuple[object, ...]]:
    return [
        (bytes(s.table.data), s.position, s.velocity, s.temperature, s.overheated,
         s.overload_latched)
        for s in emulator.bus.servos.values()
    ]  # fmt: skip


def _ops(rng: random.Random, ids: list[int]) -> Callable[[Emulator], int | None]:
    """One random thing that happens to a robot, the same for any emulator it is given."""
    dxl_id, roll = rng.choice(ids), rng.random()
    goal, flag = rng.randrange(1024, 3072), rng.randrange(2)
    speed, limit = rng.choice([0, 1, 50, 1023]), rng.choice([0, 300, 1023])
    load, volts = rng.choice([0.0, 0.0, 0.4, -1.0]), rng.choice([12.0, 12.0, 8.0, 16.5])
    address, byte = rng.randrange(24, 50), rng.randrange(256)

    def op(emulator: Emulator) -> int | None:
        """The error bits of a write's status packet; None for anything else."""
        servo, api = emulator.bus.servo(dxl_id), emulator.api
        if roll < 0.15:
            return servo.write(MX28.GOAL_POSITION.value.address, goal.to_bytes(2, "little"))
        if roll < 0.22:
            return servo.write(MX28.TORQUE_ENABLE.value.address, bytes([flag]))
        if roll < 0.26:
            return servo.write(MX28.MOVING_SPEED.value.address, speed.to_bytes(2, "little"))
        if roll < 0.29:
            return servo.write(MX28.TORQUE_LIMIT.value.address, limit.to_bytes(2, "little"))
        if roll < 0.32:
            api.set_external_load(dxl_id, load)
        elif roll < 0.34:
            api.set_voltage(volts)
        elif roll < 0.36:
            api.overheat(dxl_id, bool(flag))
        elif roll < 0.38:
            return servo.write(address, bytes([byte]))
        elif roll < 0.385:
            emulator.bus.restore(power=bool(flag))
        return None

    return op


def _afresh(servo: Servo) -> None:
    """The servo finds whether its motor drives, its load and a write's alarm bits where it
    uses them, never passing on what it found before."""
    write_present, after_write = servo._write_present, servo.after_write

    def present(drives: bool, load: float) -> None:  # not what the step found: afresh
        drives = servo.drives()
        load = servo._load(drives)
        write_present(drives, load)

    def written(changed: list) -> int:
        after_write(changed)
        return servo.alarm_bits()

    servo._write_present = present  # type: ignore[method-assign]
    servo.after_write = written  # type: ignore[method-assign]


@pytest.mark.parametrize("seed", range(6))
def test_a_servo_skipped_at_rest_reads_as_if_it_had_been_stepped(seed: int) -> None:
    skipping = Emulator(EmulatorSettings.load(realtime=False))
    stepping = Emulator(EmulatorSettings.load(realtime=False))
    full_steps = [0]
    for servo in stepping.bus.servos.values():
        servo._rest_key = lambda: None  # type: ignore[method-assign]  # never at rest
        _afresh(servo)
    for servo in skipping.bus.servos.values():
        whole = servo._full_step

        def counted(dt: float, whole: Callable[[float], None] = whole) -> None:
            full_steps[0] += 1
            whole(dt)

        servo._full_step = counted  # type: ignore[method-assign]
    for emulator in (skipping, stepping):
        emulator.bus.restore(power=True)
        emulator.advance(1.0)
        for servo in emulator.bus.servos.values():  # torque on, as the daemon leaves them
            servo.write(MX28.TORQUE_ENABLE.value.address, b"\x01")
    assert skipping.bus.servo_power
    rng = random.Random(seed)
    ids = sorted(skipping.bus.servos)
    steps = 0
    for _ in range(600):
        op = _ops(rng, ids)
        assert op(skipping) == op(stepping)
        dt = rng.choice([0.0005, 0.004, 0.004, 0.02, 0.3])
        skipping.bus.step(dt)
        stepping.bus.step(dt)
        steps += len(ids)
        assert _state(skipping) == _state(stepping)
    # Not vacuous: many servo steps were skipped, and many were not.
    assert steps / 10 < full_steps[0] < steps * 0.9, (full_steps[0], steps)


def _bulk(length: int, address: int) -> bytes:
    return bytes([0x00, *(b for i in range(1, 21) for b in (length, i, address)), 30, 200, 24])


# The daemon's sensor read, and now and then another block of the same servos.
SENSORS, OTHERS = _bulk(8, 36), (_bulk(6, 36), _bulk(8, 30))


def _eeprom_ops(rng: random.Random, ids: list[int]) -> Callable[[Emulator], None]:
    """What else a read depends on: the reply settings, the alarm limits, a silenced servo."""
    # Limits on a few servos, so each goes back and forth; silence on any.
    dxl_id, silenced, roll = rng.choice(ids[:3]), rng.choice(ids), rng.random()
    level, delay = rng.choice([0, 1, 2, 2]), rng.choice([0, 0, 250])
    # Limits that put the servo (at 35 °C, 12 V) in and out of its alarms, back and forth.
    limit, value = rng.choice([
        (MX28.TEMPERATURE_LIMIT, rng.choice([20, 80])),
        (MX28.MIN_VOLTAGE_LIMIT, rng.choice([60, 130])),
        (MX28.MAX_VOLTAGE_LIMIT, rng.choice([160, 100])),
    ])  # fmt: skip

    def op(emulator: Emulator) -> None:
        servo = emulator.bus.servo(dxl_id)
        if roll < 0.03:
            servo.write(MX28.STATUS_RETURN_LEVEL.value.address, bytes([level]))
        elif roll < 0.06:
            servo.write(MX28.RETURN_DELAY_TIME.value.address, bytes([delay]))
        elif roll < 0.16:
            servo.write(limit.value.address, bytes([value]))
        elif roll < 0.18:
            emulator.api.silence(silenced, level == 0)

    return op


@pytest.mark.parametrize("seed", range(6))
def test_a_bulk_read_answered_again_reads_as_one_answered_anew(seed: int) -> None:
    """A device whose read changes nothing gives its last bulk-read reply again while nothing
    it depends on changed (``Bus.reuse_replies``): the replies are byte for byte those of an
    emulator that builds every one."""
    # One seed: the CM-730's IMU noise draws the same numbers in both.
    reusing = Emulator(EmulatorSettings.load(realtime=False, seed=seed + 1))
    building = Emulator(EmulatorSettings.load(realtime=False, seed=seed + 1))
    building.bus.reuse_replies = False
    reads = [0]
    for servo in reusing.bus.servos.values():
        read = servo.read

        def counted(address: int, length: int, read: Callable = read) -> tuple[bytes, int]:
            reads[0] += 1
            return read(address, length)

        servo.read = counted  # type: ignore[method-assign]
    for emulator in (reusing, building):
        emulator.bus.restore(power=True)
        emulator.advance(1.0)
        for servo in emulator.bus.servos.values():
            servo.write(MX28.TORQUE_ENABLE.value.address, b"\x01")
    rng = random.Random(seed)
    ids = sorted(reusing.bus.servos)
    answered = 0
    for _ in range(600):
        # Half as eventful as the life above, so that servos come to rest between events.
        calm = rng.random() < 0.5
        for op in (_ops(rng, ids), _eeprom_ops(rng, ids)):
            if not calm:
                op(reusing)
                op(building)
        dt = rng.choice([0.0005, 0.004, 0.004, 0.02, 0.3])
        for emulator in (reusing, building):
            emulator.bus.step(dt)
        params = SENSORS if rng.random() < 0.9 else rng.choice(OTHERS)
        frame = Packet(BROADCAST_ID, Instruction.BULK_READ, params)
        got, want = reusing.bus.handle(frame), building.bus.handle(frame)
        assert got == want
        answered += sum(r.device_id != 200 for r in got)
        assert _state(reusing) == _state(building)
    # Not vacuous: many replies were given again, and many were built.
    assert answered / 10 < reads[0] < answered * 0.9, (reads[0], answered)


def _standing() -> Emulator:
    emulator = Emulator(EmulatorSettings.load(realtime=False, seed=1))
    emulator.bus.restore(power=True)
    emulator.advance(1.0)
    return emulator


def _answers(emulator: Emulator) -> list[int]:
    frame = Packet(BROADCAST_ID, Instruction.BULK_READ, SENSORS)
    return [r.device_id for r in emulator.bus.handle(frame)]


def test_a_servo_silenced_at_rest_answers_again_once_heard() -> None:
    emulator = _standing()
    assert _answers(emulator) == [*range(1, 21), 200]
    emulator.api.silence(5)
    assert _answers(emulator) == [1, 2, 3, 4]  # the chain waits for 5 for ever
    emulator.api.silence(5, False)
    assert _answers(emulator) == [*range(1, 21), 200]


def test_a_read_that_raises_an_alarm_raises_it_each_time_it_is_due() -> None:
    """Reading a servo over its temperature limit latches OVERHEATING (a read that changes
    the servo); with the limit raised and lowered again in between, the next read latches
    it again, as the first did."""
    emulator = _standing()
    servo = emulator.bus.servo(1)
    limit = MX28.TEMPERATURE_LIMIT.value.address
    for _ in range(2):
        servo.write(limit, bytes([20]))  # below the room's 35 °C
        servo.overheated = False  # as the write left it: no read since
        _answers(emulator)
        assert servo.overheated
        servo.write(limit, bytes([80]))
        servo.overheated = False
