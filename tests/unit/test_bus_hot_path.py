"""The per-tick bus code's shortcuts agree with the plain definitions they stand in for."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from config.loader import load_all, robot_from_dict
from robot_daemon.bus.bulk_receive import (
    LATENESS_STEP_MS,
    MAX_LATENESS_MS,
    BulkPlan,
    BulkResult,
    next_lateness,
    receive,
)
from robot_daemon.bus.calibration import Calibration
from robot_daemon.bus.dxl import ReplyBudget
from robot_daemon.bus.packet import status_packet
from robot_daemon.bus.transport import Transport
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


@pytest.mark.parametrize("dps", [500.0, 2000.0])
def test_imu_si_is_the_unit_conversions(dps: float) -> None:
    """The frame's gyro and accelerometer, written out, are units' conversions to the bit."""
    from robot_daemon.bus.state import imu_si
    from robot_daemon.bus.tables import IMU_ACCEL_AXES, IMU_GYRO_AXES

    for r in range(units.IMU_MAX + 1):
        counts = [r, units.IMU_MAX - r, (r * 7) % (units.IMU_MAX + 1)]
        gyro, accel = imu_si(counts, counts, dps)
        assert gyro.tolist() == [
            s * units.gyro_raw_to_rad_s(c, dps) for c, (_, s) in zip(counts, IMU_GYRO_AXES,
                                                                     strict=True)
        ]
        assert accel.tolist() == [
            s * units.accel_raw_to_ms2(c) for c, (_, s) in zip(counts, IMU_ACCEL_AXES,
                                                              strict=True)
        ]


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


class _Chunks(Transport):
    """Hands out the given chunks one read at a time, on a clock that never waits."""

    def __init__(self, chunks: list[bytes]) -> None:
        super().__init__("chunks")
        self.set_baud(1_000_000)
        self.chunks = list(chunks)
        self.now = 0.0

    def open(self, baudrate: int) -> None:
        pass

    def close(self) -> None:
        pass

    def getCurrentTime(self) -> float:
        return self.now

    def idle_until(self, clock_ms: float) -> None:
        self.now = max(self.now, clock_ms)

    def read_chunk(self, deadline_ms: float) -> bytes:
        return self.chunks.pop(0) if self.chunks else b""


def _received(plan: BulkPlan, chunks: list[bytes]) -> tuple[Any, ...]:
    out = BulkResult()
    got = receive(_Chunks(chunks), plan, 0.0, 0.0, out)
    return out.data, list(out.errors.items()), out.corrupt, got.missing, got.heard


@pytest.mark.parametrize("seed", range(40))
def test_a_whole_answer_at_once_is_taken_as_reply_by_reply(seed: int) -> None:
    """The bulk read's whole-answer shortcut (one unpack, one checksum pass) gives what the
    reply-by-reply loop gives: data, error bits, corrupt replies, who is missing or heard."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 23))
    ids = [int(i) for i in rng.choice(np.arange(1, 60), n, replace=False)]
    blocks = [(i, 24, int(rng.integers(1, 31))) for i in ids]
    plan = BulkPlan.make(blocks, ReplyBudget(), 0.01)
    replies = [
        bytearray(status_packet(i, int(rng.choice([0, 0, 0, 4, 32])), rng.bytes(length)))
        for i, _, length in blocks
    ]
    fault = int(rng.integers(0, 4))
    bad = int(rng.integers(0, n))
    if fault == 1:
        replies[bad][-1] ^= 0x01  # a bad checksum
    elif fault == 2:
        replies[bad][2] = 99  # a header naming someone else
    whole = b"".join(replies)
    # The loop's way: the first reply alone, then the rest (never all at once).
    cut = len(replies[0])
    one_by_one = _received(plan, [whole[:cut], whole[cut:]] if n > 1 else [whole[:-1], whole[-1:]])
    at_once = _received(plan, [whole])
    assert at_once == one_by_one
    if fault == 0:
        assert at_once[0] == {i: bytes(r[5:-1]) for i, r in zip(ids, replies, strict=True)}


class _SyncWrites:
    """The bus's sync writes, as the rows' bytes handed to it."""

    def __init__(self) -> None:
        self.rows: list[tuple[int, int, bytes]] = []

    def sync_write_rows(self, start: int, length: int, rows: bytes) -> int:
        self.rows.append((start, length, rows))
        return len(rows)


def _bus_writing_to(writes: _SyncWrites) -> Any:
    from robot_daemon.bus.robot_bus import RobotBus

    settings = load_all()
    rb = RobotBus("none", robot_from_dict(settings["robot"]), settings, lambda *a, **k: None)
    rb.dxl = writes  # type: ignore[assignment]
    rb.calibration.set_offset(4, 7.5)
    # Joint 20 allowed further than the servo turns: its goals past 0..4095 are clamped there.
    rb.calibration.min[20], rb.calibration.max[20] = -3.5, 3.5
    rb.calibration.set_offset(20, 20.0)
    rb.state.torque[1:] = True
    return rb


@pytest.mark.parametrize("seed", range(8))
def test_goals_written_as_a_batch_are_the_goals_written_one_by_one(seed: int) -> None:
    """A tick's goals converted as one batch against a template of rows give the bytes, the
    state's goals and the counters the goal-by-goal loop gives, over walks of random ticks:
    joint sets and gains that repeat or change, torque off, goals outside their limits or
    not a number."""
    from robot_daemon.frames import Targets

    rng = np.random.default_rng(seed)
    fast_w, each_w = _SyncWrites(), _SyncWrites()
    fast, each = _bus_writing_to(fast_w), _bus_writing_to(each_w)
    legs = [7, 9, 11, 13, 15, 17, 8, 10, 12, 14, 16, 18]
    sets = [[*legs, 1, 2, 3, 4, 5, 6], list(range(1, 21)), [19, 20], [5], legs[::-1]]
    gain_sets: list[dict[int, tuple[int, int, int]]] = [
        {}, dict.fromkeys(legs, (32, 0, 0)), {**dict.fromkeys(legs, (24, 2, 1)), 1: (8, 0, 0)},
    ]
    for _ in range(300):
        ids = sets[int(rng.integers(len(sets)))] if rng.random() < 0.3 else sets[0]
        gains = dict(gain_sets[int(rng.integers(len(gain_sets)))]) if rng.random() < 0.2 \
            else dict(gain_sets[1])
        rads = rng.uniform(-1.2, 1.2, len(ids))
        if 20 in ids:
            rads[ids.index(20)] = rng.uniform(-3.5, 3.5)
        if rng.random() < 0.1:
            rads[int(rng.integers(len(ids)))] = rng.choice([-4.0, 4.0, math.inf])
        nan = rng.random() < 0.03
        if nan:
            rads[int(rng.integers(len(ids)))] = math.nan
        if rng.random() < 0.1:
            off = int(rng.integers(1, 21))
            fast.state.torque[off] = each.state.torque[off] = False
        elif rng.random() < 0.2:
            fast.state.torque[1:] = each.state.torque[1:] = True
        targets = Targets(goal=dict(zip(ids, rads.tolist(), strict=True)), gains=gains)
        # A NaN goal of a torqued joint is refused (round's ValueError), by both ways alike.
        refused: list[str | None] = []
        for write in (each._write_each, fast.write_targets):
            try:
                write(targets)
                refused.append(None)
            except ValueError as exc:
                refused.append(str(exc))
        assert refused[0] == refused[1]
        assert nan or refused[0] is None
        assert fast_w.rows == each_w.rows
        assert np.array_equal(fast.state.goal, each.state.goal)
        assert fast.counters == each.counters
    assert fast._write_plans  # the batch's way was taken


def test_cm730_status_reads_each_field_where_its_register_is() -> None:
    """status's CM-730 fields from offsets looked up once: each the value its register
    (``cm730_field``) holds, in random blocks; an all-zero block is the CM-730 not read yet."""
    from robot_daemon.bus.state import cm730_field, cm730_status
    from robot_daemon.bus.tables import CM730

    rng = np.random.default_rng(48)
    for _ in range(2_000):
        block = rng.integers(0, 256, 30, dtype=np.uint8).tobytes()
        got = cm730_status(block)
        buttons = cm730_field(block, CM730.BUTTON)
        assert got == {
            "leds": {
                "head": list(units.color_word_to_rgb(cm730_field(block, CM730.LED_HEAD))),
                "eye": list(units.color_word_to_rgb(cm730_field(block, CM730.LED_EYE))),
                "panel": cm730_field(block, CM730.LED_PANEL),
            },
            "buttons": {"mode": bool(buttons & 1), "start": bool(buttons & 2)},
            "voltage": cm730_field(block, CM730.VOLTAGE) / 10.0,
            "power": bool(cm730_field(block, CM730.DXL_POWER)),
        }
    assert cm730_status(bytes(30)) == cm730_status(b"") == {"leds": {}, "buttons": {},
                                                             "voltage": 0.0}
