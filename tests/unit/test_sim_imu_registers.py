"""The CM-730's refresh writes its IMU registers from an axis map's signs and addresses kept
while the map is the same, and from readings converted once while what they convert is the
same (``CM730Device.refresh``, before each of its reads): every register must be what the
conversions give, for any body motion, noise, full scale and axis map, and the noise must take
the same draws from the generator."""

from __future__ import annotations

import random

import numpy as np
import pytest

from robot_daemon.bus import tables
from robot_daemon.bus.tables import CM730
from robot_daemon.emulator import devices
from robot_daemon.emulator.devices import CM730Device, Environment
from schemas import units


def reference(cm: CM730Device, rng: np.random.Generator) -> bytes:
    """The registers as units' conversions give them through the axis map read afresh,
    drawing the noise from ``rng``."""
    d = bytearray(cm.table.data)
    d[CM730.VOLTAGE.value.address] = max(0, min(255, round(cm.env.voltage * 10)))
    gyro_axes, accel_axes = devices.IMU_GYRO_AXES, devices.IMU_ACCEL_AXES
    raws: list[float] = [
        units.rad_s_to_gyro_raw(s * v, cm.gyro_full_scale_dps)
        for (_, s), v in zip(gyro_axes, cm.gyro, strict=True)
    ]
    raws += [units.ms2_to_accel_raw(s * v) for (_, s), v in zip(accel_axes, cm.accel, strict=True)]
    if cm.imu_noise > 0:
        noise = rng.normal(0.0, cm.imu_noise, 6).tolist()
        raws = [r + n for r, n in zip(raws, noise, strict=True)]
    for (member, _), raw in zip((*gyro_axes, *accel_axes), raws, strict=True):
        value = max(0, min(units.IMU_MAX, round(raw)))
        d[member.value.address] = value & 0xFF
        d[member.value.address + 1] = (value >> 8) & 0xFF
    return bytes(d)


def _value(r: random.Random) -> float:
    """A body rate or force: small, large enough to clamp, on a count's half, or zero."""
    kind = r.random()
    if kind < 0.1:
        return 0.0
    if kind < 0.2:
        return r.choice([-1.0, 1.0]) * r.uniform(50.0, 1e6)  # far past the range: clamped
    if kind < 0.3:  # close to a rounding tie of one count
        return (r.randrange(-400, 400) + 0.5) * units.GRAVITY * units.ACCEL_G_PER_COUNT
    return r.uniform(-40.0, 40.0)


@pytest.mark.parametrize("seed", range(4))
def test_the_imu_registers_are_units_conversions(seed: int) -> None:
    r = random.Random(seed)
    env = Environment()
    cm = CM730Device(env, np.random.default_rng(seed))
    twin = np.random.default_rng(seed)  # the same draws, for the reference's noise
    for _ in range(3000):
        # The refresh keeps its conversions while what it converts is the same: the body felt
        # the same, or only one of the vectors or the full scale changed, or equal new vectors.
        roll = r.random()
        if roll < 0.5:
            cm.gyro = (_value(r), _value(r), _value(r))
        elif roll < 0.6:
            cm.gyro = (cm.gyro[0], cm.gyro[1], cm.gyro[2])
        roll = r.random()
        if roll < 0.5:
            cm.accel = (_value(r), _value(r), _value(r))
        elif roll < 0.6:
            cm.accel = (cm.accel[0], cm.accel[1], cm.accel[2])
        cm.imu_noise = r.choice([0.0, 1.0, 3.5, 400.0])
        if r.random() < 0.3:
            cm.gyro_full_scale_dps = r.choice([500.0, 250.0, 2000.0, 333.3])
        env.voltage = r.choice([12.0, 8.1, 16.5, 30.0])
        expected = reference(cm, twin)
        cm.refresh()
        assert bytes(cm.table.data) == expected, (cm.gyro, cm.accel, cm.imu_noise)


def test_an_axis_map_changed_at_run_time_is_followed(monkeypatch: pytest.MonkeyPatch) -> None:
    cm = CM730Device(Environment(), np.random.default_rng(1))
    twin = np.random.default_rng(1)
    cm.gyro, cm.accel = (0.3, -1.2, 2.0), (1.0, -2.0, 9.0)
    expected = reference(cm, twin)
    cm.refresh()  # the shipped map's signs and addresses kept
    assert bytes(cm.table.data) == expected
    flipped = tuple((m, -s) for m, s in tables.IMU_GYRO_AXES)
    swapped = (tables.IMU_ACCEL_AXES[1], tables.IMU_ACCEL_AXES[0], tables.IMU_ACCEL_AXES[2])
    monkeypatch.setattr(devices, "IMU_GYRO_AXES", flipped)
    monkeypatch.setattr(devices, "IMU_ACCEL_AXES", swapped)
    expected = reference(cm, twin)
    cm.refresh()
    assert bytes(cm.table.data) == expected
