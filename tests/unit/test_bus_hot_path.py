"""The per-tick bus code's shortcuts agree with the plain definitions they stand in for."""

from __future__ import annotations

import math

import numpy as np
import pytest

from config.loader import load_all, robot_from_dict
from robot_daemon.bus.bulk_receive import LATENESS_STEP_MS, MAX_LATENESS_MS, next_lateness
from robot_daemon.bus.calibration import Calibration
from schemas import units


@pytest.fixture(scope="module")
def calibration() -> Calibration:
    robot = robot_from_dict(load_all()["robot"])
    cal = Calibration(robot)
    cal.set_offset(robot.ids[3], 7.5)  # an offset and both directions in play
    return cal


def test_goal_raw_is_to_raw_after_clamp(calibration: Calibration) -> None:
    for jid in range(1, 21):
        for rad in np.linspace(-4.0, 4.0, 97):
            want = calibration.to_raw(jid, calibration.clamp(jid, float(rad)))
            outside = not calibration.in_limits(jid, float(rad))
            assert calibration.goal_raw(jid, rad) == (want, outside), (jid, rad)
            assert calibration.goal_raw(jid, float(rad)) == (want, outside)


def test_goal_raw_follows_a_new_offset(calibration: Calibration) -> None:
    before, _ = calibration.goal_raw(5, 0.0)
    calibration.set_offset(5, 10.0)
    after, _ = calibration.goal_raw(5, 0.0)
    calibration.set_offset(5, 0.0)
    assert abs(after - before) == round(math.radians(10.0) / units.RAD_PER_UNIT)


def test_speed_and_load_tables_are_the_conversions() -> None:
    raw = np.arange(0x800)
    assert np.array_equal(units.SPEED_RAD_S_TABLE, units.speed_raw_to_rad_s(raw))
    assert np.array_equal(units.LOAD_FRACTION_TABLE, units.load_raw_to_fraction(raw))
    assert units.SPEED_RAD_S_TABLE[0x400 | 5] == units.speed_raw_to_rad_s(0x400 | 5) < 0


def test_lateness_comes_down_after_a_read_that_was_all_in() -> None:
    assert next_lateness(0.5, 1, 0.9) == pytest.approx(0.5 - LATENESS_STEP_MS)
    assert next_lateness(0.0, 1, 0.3) == 0.0  # never below the wire time


def test_lateness_goes_towards_what_was_seen_after_more_reads() -> None:
    late = 0.0
    for _ in range(20):
        late = next_lateness(late, 3, 0.8)
    assert late == pytest.approx(0.8, abs=1e-3)
    assert next_lateness(0.4, 2, 0.1) == 0.4  # seen before the estimate: no faster than it


def test_lateness_is_bounded_whatever_was_seen() -> None:
    assert next_lateness(1.9, 2, 500.0) == MAX_LATENESS_MS
