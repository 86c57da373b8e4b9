"""A servo at rest skips its step (``Servo._rest_key``): that must never change what the bus
reads. Two emulators live the same seeded random life (goals, torque, speed and torque limits,
loads, heat, supply voltage, writes of any RAM register, steps of any length); one always runs
the whole step. After every step every servo's control table and state are the same."""

from __future__ import annotations

import random
from collections.abc import Callable

import pytest

from robot_daemon.bus.tables import MX28
from robot_daemon.emulator.emulator import Emulator
from robot_daemon.emulator.settings import EmulatorSettings


def _state(emulator: Emulator) -> list[tuple[object, ...]]:
    return [
        (bytes(s.table.data), s.position, s.velocity, s.temperature, s.overheated,
         s.overload_latched)
        for s in emulator.bus.servos.values()
    ]  # fmt: skip


def _ops(rng: random.Random, ids: list[int]) -> Callable[[Emulator], None]:
    """One random thing that happens to a robot, the same for any emulator it is given."""
    dxl_id, roll = rng.choice(ids), rng.random()
    goal, flag = rng.randrange(1024, 3072), rng.randrange(2)
    speed, limit = rng.choice([0, 1, 50, 1023]), rng.choice([0, 300, 1023])
    load, volts = rng.choice([0.0, 0.0, 0.4, -1.0]), rng.choice([12.0, 12.0, 8.0, 16.5])
    address, byte = rng.randrange(24, 50), rng.randrange(256)

    def op(emulator: Emulator) -> None:
        servo, api = emulator.bus.servo(dxl_id), emulator.api
        if roll < 0.15:
            servo.write(MX28.GOAL_POSITION.value.address, goal.to_bytes(2, "little"))
        elif roll < 0.22:
            servo.write(MX28.TORQUE_ENABLE.value.address, bytes([flag]))
        elif roll < 0.26:
            servo.write(MX28.MOVING_SPEED.value.address, speed.to_bytes(2, "little"))
        elif roll < 0.29:
            servo.write(MX28.TORQUE_LIMIT.value.address, limit.to_bytes(2, "little"))
        elif roll < 0.32:
            api.set_external_load(dxl_id, load)
        elif roll < 0.34:
            api.set_voltage(volts)
        elif roll < 0.36:
            api.overheat(dxl_id, bool(flag))
        elif roll < 0.38:
            servo.write(address, bytes([byte]))
        elif roll < 0.385:
            emulator.bus.restore(power=bool(flag))

    return op


@pytest.mark.parametrize("seed", range(6))
def test_a_servo_skipped_at_rest_reads_as_if_it_had_been_stepped(seed: int) -> None:
    skipping = Emulator(EmulatorSettings.load(realtime=False))
    stepping = Emulator(EmulatorSettings.load(realtime=False))
    full_steps = [0]
    for servo in stepping.bus.servos.values():
        servo._rest_key = lambda: None  # type: ignore[method-assign]  # never at rest
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
        op(skipping)
        op(stepping)
        dt = rng.choice([0.0005, 0.004, 0.004, 0.02, 0.3])
        skipping.bus.step(dt)
        stepping.bus.step(dt)
        steps += len(ids)
        assert _state(skipping) == _state(stepping)
    # Not vacuous: many servo steps were skipped, and many were not.
    assert steps / 10 < full_steps[0] < steps * 0.9, (full_steps[0], steps)
