"""The compiled hot path (robot_daemon/_hotpath.c) gives the bits of the Python it stands in
for: the leg IK's six angles and the goals in servo units, on seeded random inputs (across the
legs' workspace and beyond it, ties of round-half-even, limits, NaN and infinities), and a walk's
every goal and sync-write packet. Skipped, named, where the extension is not built."""

from __future__ import annotations

import math
import random
import struct
import subprocess
import sys
from operator import itemgetter
from pathlib import Path
from typing import Any

import pytest

from robot_daemon import hotpath
from robot_daemon.bus.calibration import goals_raw_py
from robot_daemon.motion.walking import ik
from schemas import units

ROOT = Path(__file__).resolve().parents[2]
compiled = hotpath.compiled
pytestmark = pytest.mark.skipif(compiled is None, reason=hotpath.status)


def _bits(value: Any) -> Any:
    """Floats as their exact bits (repr tells 0.0 from -0.0; hex tells every bit apart)."""
    if isinstance(value, tuple | list):
        return [_bits(v) for v in value]
    return value.hex() if isinstance(value, float) else value


def _ik_both(point: tuple[float, ...]) -> tuple[Any, Any]:
    out = []
    for fn in (ik.leg_ik_end_point_py, compiled.leg_ik_end_point):  # type: ignore[union-attr]
        try:
            out.append(_bits(fn(*point)))
        except (ValueError, OverflowError) as exc:
            out.append(f"{type(exc).__name__}: {exc}")
    return out[0], out[1]


def test_the_gait_runs_the_compiled_ik() -> None:
    assert ik.leg_ik_end_point is compiled.leg_ik_end_point  # type: ignore[union-attr]


def test_leg_ik_gives_the_bits_of_the_python() -> None:
    rng = random.Random(37)
    reached = 0
    for i in range(200_000):
        wide = i % 4 == 0  # a quarter far outside the workspace
        span = 0.4 if wide else 0.12
        point = (rng.uniform(-span, span), rng.uniform(-span, span), rng.uniform(-0.05, 0.25),
                 rng.uniform(-3.2, 3.2) if wide else rng.uniform(-0.8, 0.8),
                 rng.uniform(-3.2, 3.2) if wide else rng.uniform(-0.8, 0.8),
                 rng.uniform(-3.2, 3.2) if wide else rng.uniform(-0.8, 0.8))
        py, c = _ik_both(point)
        assert py == c, point
        reached += py is not None
    assert reached > 100_000
    odd = [0.0, -0.0, 1e-300, -1e-300, 1e300, math.inf, -math.inf, math.nan, 0.5 * math.pi]
    for _ in range(5000):
        point = tuple(rng.choice(odd) if rng.random() < 0.3 else rng.uniform(-0.1, 0.1)
                      for _ in range(6))
        py, c = _ik_both(point)
        assert py == c, point
    # What is not six floats goes to the Python, which says what is wrong.
    assert compiled.leg_ik_end_point(0, 0, 0.05, 0, 0, 0) == ik.leg_ik_end_point_py(  # type: ignore[union-attr]
        0, 0, 0.05, 0, 0, 0)


def _goals_both(*args: Any) -> tuple[Any, Any]:
    out = []
    for fn in (goals_raw_py, compiled.goals_raw):  # type: ignore[union-attr]
        try:
            got = fn(*args)
            if got is NotImplemented:
                got = goals_raw_py(*args)
            out.append(got)
        except (ValueError, OverflowError) as exc:
            out.append(f"{type(exc).__name__}: {exc}")
    return out[0], out[1]


@pytest.mark.parametrize("k", [units.RAD_PER_UNIT, 1.0, 0.25])
def test_goals_raw_gives_the_ints_of_the_python(k: float) -> None:
    """With the servo's unit and with units where many goals land on a tie (x.5: round half to
    even), goals within and outside limits, NaN and infinities."""
    rng = random.Random(38)
    c = units.POSITION_CENTER
    refused = 0
    for _ in range(20_000):
        n = rng.choice([18, 20, 2, 1])
        sign = [rng.choice([1.0, -1.0]) for _ in range(n)]
        offset = [rng.uniform(-0.3, 0.3) if rng.random() < 0.5 else 0.0 for _ in range(n)]
        lo = [rng.uniform(-3.2, -1.5) - 1e-9 for _ in range(n)]
        hi = [rng.uniform(1.5, 3.2) + 1e-9 for _ in range(n)]
        if k == units.RAD_PER_UNIT:
            rads = [rng.uniform(-1.5, 1.5) for _ in range(n)]
        else:  # halves and quarters: exact ties after the division
            rads = [rng.randint(-12, 12) * 0.125 for _ in range(n)]
            offset = [rng.randint(-4, 4) * 0.125 for _ in range(n)]
        if rng.random() < 0.1:
            rads[rng.randrange(n)] = rng.choice([math.nan, math.inf, -math.inf, 5.0, -5.0])
        py, cc = _goals_both(sign, offset, lo, hi, rads, k, c)
        assert py == cc, (sign, offset, lo, hi, rads, k)
        refused += py is None
    assert 500 < refused < 5000


def test_goals_raw_hands_back_what_it_does_not_take() -> None:
    """A goal that is not a float, or columns of other lengths: the Python's to do."""
    one = [1.0, 1.0]
    assert compiled.goals_raw(one, [0.0, 0.0], [-1.0] * 2, [1.0] * 2, [0.5, 1], 0.1, 2048) \
        is NotImplemented  # type: ignore[union-attr]
    assert compiled.goals_raw(one, [0.0], [-1.0] * 2, [1.0] * 2, [0.5, 0.5], 0.1, 2048) \
        is NotImplemented  # type: ignore[union-attr]


WALK = """
import hashlib, random, sys
sys.path.insert(0, "tests/unit")
import numpy as np
from robot_daemon import hotpath
from tests.unit.test_motion_walking import Rig
from robot_daemon.bus.calibration import Calibration
from config.loader import load_all, robot_from_dict

rig = Rig()
cal = Calibration(robot_from_dict(load_all()["robot"]))
rng = random.Random(7)
digest = hashlib.sha256()
rig.walk.start(0.1, 0.0, 0.0)
for cmd in [(0.1, 0.0, 0.0), (0.0, 0.05, 0.0), (0.0, 0.0, 0.5), (-0.05, -0.03, -0.4),
            (0.08, 0.04, 0.3), (0.0, 0.0, 0.0)]:
    rig.walk.set_speed(*cmd)
    for _ in range(150):
        rig.gyro = np.array([512 + rng.randint(-40, 40) for _ in range(3)])
        rig.run(1)
for goals in rig.goals:
    ids = tuple(sorted(goals))
    digest.update(repr([goals[j] for j in ids]).encode())
    digest.update(repr(cal.goals_raw(ids, [goals[j] for j in ids])).encode())
print(hotpath.status.split(" (")[0], len(rig.goals), digest.hexdigest())
"""


def test_a_walk_gives_the_same_goals_and_servo_units_either_way() -> None:
    """A walk through six commands with gyro feedback, run with the compiled path and with
    DARWIN_HOTPATH=python: every goal (rad) and every goal in servo units the same."""
    runs = []
    for env in ({}, {"DARWIN_HOTPATH": "python"}):
        proc = subprocess.run([sys.executable, "-c", WALK], capture_output=True, text=True,
                              cwd=ROOT, env={**__import__("os").environ, **env}, timeout=300)
        assert proc.returncode == 0, proc.stderr
        runs.append(proc.stdout.split())
    assert runs[0][:2] == ["hot", "path:"] and runs[0][2] == "compiled"
    assert runs[1][2] == "Python"
    assert int(runs[0][3]) > 800
    assert runs[0][3:] == runs[1][3:]


def _value(rng: random.Random, depth: int = 0, dicts: bool = False) -> Any:
    kind = rng.randrange(9 if depth < 3 else 7)
    if kind == 0:
        return rng.choice([None, True, False])
    if kind == 1:  # every int form's edges
        edge = rng.choice([0, 1, 31, 32, 127, 128, 255, 256, 65535, 65536, 2**31, 2**32, 2**62])
        return rng.choice([edge, edge - 1, -edge, -edge - 1])
    if kind == 2:
        return rng.randint(-(2**63), 2**63 - 1)
    if kind == 3:
        return rng.choice([rng.uniform(-1e3, 1e3), 0.0, -0.0, math.inf, -math.inf, math.nan,
                           5e-324, 1.7e308])
    if kind == 4:
        return "".join(rng.choice("abcé€😀 ") for _ in range(rng.choice([0, 5, 31, 32, 300])))
    if kind == 5:
        return rng.randbytes(rng.choice([0, 3, 255, 256, 70000]))
    if kind == 6:
        return rng.uniform(-3.2, 3.2)
    if depth == 0 and rng.random() < 0.3:  # the array forms' edges, flat
        n = rng.choice([0, 15, 16, 20, 65535, 65536])
        items = [rng.uniform(-1, 1), rng.randint(-99, 99), True] * (n // 3 + 1)
    else:
        n = rng.choice([0, 2, 3, 16])
        items = [_value(rng, depth + 1) for _ in range(n)]
    if dicts and rng.random() < 0.4:  # a map: its header's forms' edges, keys of any kind
        n = rng.choice([0, 1, 15, 16, 17]) if depth or rng.random() < 0.9 else 65536
        keys = [rng.choice([f"k{i}", i, -i, float(i) + 0.5, b"k%d" % i, None]) for i in range(n)]
        return {k: _value(rng, depth + 1, dicts) for k in keys}
    return items[:n] if kind == 7 else tuple(items[:n])


def test_pack_fields_gives_msgpacks_bytes() -> None:
    """head, each key and its value packed, tail: msgpack's bytes for every type and size
    form it packs (ints at each form's edges, floats, str, bytes, lists and tuples nested);
    NotImplemented for what it leaves to msgpack."""
    import msgpack

    pack = msgpack.Packer(use_bin_type=True).pack
    rng = random.Random(39)
    for _ in range(1000):
        n = rng.randrange(1, 12)
        keys = tuple(pack(f"k{i}") for i in range(n))
        values = [_value(rng) for _ in range(n)]
        want = b"H" + b"".join(k + pack(v) for k, v in zip(keys, values, strict=True)) + b"T"
        assert compiled.pack_fields(b"H", keys, values, b"T") == want  # type: ignore[union-attr]
    for other in (2**63, 2**64 - 1, 2**70, 1.5j, [1, [2, {3}]], {"a": {1, 2}}, "\ud800"):
        assert compiled.pack_fields(b"", (b"k",), [other], b"") is NotImplemented  # type: ignore[union-attr]


class _Str(str):
    pass


def test_packb_gives_msgpacks_bytes() -> None:
    """packb (status and events through the publisher, broadcast.as_payload): msgpack's bytes
    for every form pack_fields packs plus maps (their header forms' edges, keys of any kind,
    nested); NotImplemented, for msgpack to pack, for what it leaves."""
    import msgpack

    pack = msgpack.Packer(use_bin_type=True).pack
    rng = random.Random(37)
    for _ in range(2000):
        value = {f"f{i}": _value(rng, 1, dicts=True) for i in range(rng.randrange(0, 20))}
        if rng.random() < 0.2:
            value = _value(rng, 0, dicts=True)
        assert compiled.packb(value) == pack(value)  # type: ignore[union-attr]
    # Every header form of both (fix, 16-bit, 32-bit): one packer of headers serves both.
    for n in (15, 16, 65535, 65536):
        for value in ([0] * n, {str(i): 0 for i in range(n)}):
            assert compiled.packb(value) == pack(value)  # type: ignore[union-attr]
    nine = deep = {"leaf": 1.0}
    for _ in range(8):
        nine = {"down": nine}
    assert compiled.packb(nine) == pack(nine)  # type: ignore[union-attr]
    for other in (2**63, 1.5j, {"a": {1, 2}}, {_Str("k"): 1}, {"k": _Str("v")}, {"down": nine},
                  {(1, 2): {3: [{"x": 2**70}]}}, "\ud800"):
        assert compiled.packb(other) is NotImplemented  # type: ignore[union-attr]
    del deep


def test_status_and_events_are_packed_compiled_with_encodes_bytes() -> None:
    """The daemon's status and an event, as the publisher sends them (broadcast.as_payload):
    the bytes of ``encode``, packed by the compiled packer (not handed back to msgpack)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from tick_count import one_tick, tick_daemon

    from robot_daemon.engine.broadcast import LoopFacts, as_payload, status_message
    from schemas.messages import Event, encode

    daemon = tick_daemon(True, seconds=1.0)
    for _ in range(40):
        one_tick(daemon)
    facts = LoopFacts(state="running", bus_errors=3, scheduling="SCHED_OTHER", events_dropped=0)
    status = status_message(daemon.status_sources, daemon.snapshot, facts)
    event = Event(kind="fault", message="m", data={"id": 3, "celsius": 71.5, "ids": [1, 2]},
                  seq=9)
    for msg in (status, event):
        assert compiled.packb(msg.to_dict()) is not NotImplemented  # type: ignore[union-attr]
        assert as_payload(msg) == encode(msg)


def test_positions_list_gives_the_floats_of_the_python(monkeypatch: pytest.MonkeyPatch) -> None:
    """The snapshot's goals in rad (Calibration.positions_list) over every raw position of a
    servo's range and beyond, with both directions and random offsets."""
    import robot_daemon.bus.calibration as calibration
    from config.loader import load_all, robot_from_dict

    cal = calibration.Calibration(robot_from_dict(load_all()["robot"]))
    rng = random.Random(40)
    for jid in range(1, 21):
        cal.set_offset(jid, rng.uniform(-30, 30))
    raws = [[rng.randrange(-5000, 9000) for _ in range(21)] for _ in range(300)]
    raws.append(list(range(21)))
    raws += [list(range(start, start + 21)) for start in range(0, 4096, 21)]
    got = [cal.positions_list(r) for r in raws]
    monkeypatch.setattr(calibration, "_compiled", None)
    want = [cal.positions_list(r) for r in raws]
    assert _bits(got) == _bits(want)
    assert compiled.positions_list([1.0], [1.0], [0.0], 0.1, 2048) is NotImplemented  # type: ignore[union-attr]
    assert compiled.positions_list([2**40], [1.0], [0.0], 0.1, 2048) is NotImplemented  # type: ignore[union-attr]


def test_leg_servo_angles_gives_the_python_s_dict(monkeypatch: pytest.MonkeyPatch) -> None:
    """The gait's servo angles of a leg (ids, directions, the hip pitch offset) compiled as a
    whole: the same dict to the bit (repr: keys in order, every float), None alike."""
    rng = random.Random(41)
    cases = []
    for i in range(50_000):
        span = 0.3 if i % 5 == 0 else 0.1
        point = (rng.uniform(-span, span), rng.uniform(-span, span), rng.uniform(-0.03, 0.2),
                 rng.uniform(-0.8, 0.8), rng.uniform(-0.8, 0.8), rng.uniform(-0.8, 0.8))
        cases.append((rng.choice(["right", "left"]), point, rng.uniform(-0.5, 0.5)))
    cases += [("left", (0.0, 0.0, 0.05, math.inf, 0.0, 0.0), 0.1),
              ("right", [0.01, 0.0, 0.05, 0.0, 0.0, 0.0], 0),
              ("right", (0, 0, 0.05, 0, 0, 0), 0.2)]

    def run() -> list[str]:
        out = []
        for side, point, offset in cases:
            try:
                out.append(repr(ik.leg_servo_angles(side, point, offset)))  # type: ignore[arg-type]
            except ValueError as exc:
                out.append(f"ValueError: {exc}")
        return out

    got = run()
    monkeypatch.setattr(ik, "_servo_angles", None)
    want = run()
    assert sum(g != "None" for g in got) > 30_000
    assert got == want


def _bulk_answer(rng: random.Random, fault: int) -> tuple[Any, bytes]:
    """A bulk read's plan and its whole answer, good or with one fault: a bad checksum, a
    header naming someone else or of another length, a byte short or over."""
    from robot_daemon.bus.bulk_receive import BulkPlan
    from robot_daemon.bus.dxl import ReplyBudget
    from robot_daemon.bus.packet import status_packet

    ids = rng.sample(range(0, 254), rng.randrange(1, 24))
    blocks = [(i, 24, rng.randrange(0, 40)) for i in ids]
    plan = BulkPlan.make(blocks, ReplyBudget(), 0.01)
    replies = [bytearray(status_packet(i, rng.choice([0, 0, 0, 4, 32, 128]), rng.randbytes(n)))
               for i, _, n in blocks]
    bad = rng.randrange(len(replies))
    if fault == 1:
        replies[bad][-1] ^= 1 << rng.randrange(8)
    elif fault == 2:
        replies[bad][2] ^= 1 << rng.randrange(8)
    elif fault == 3:
        replies[bad][3] ^= 1 << rng.randrange(8)
    elif fault == 4:
        replies[bad][rng.randrange(2)] = rng.randrange(255)
    elif fault == 5:
        replies[bad][4 + rng.randrange(len(replies[bad]) - 4)] ^= 0xFF
    whole = b"".join(replies)
    if fault == 6:
        whole = whole[:-1]
    elif fault == 7:
        whole += b"\xff"
    return plan, whole


def test_take_whole_takes_and_refuses_what_the_python_does() -> None:
    """The bulk read's whole answer taken (every reply's data and error bits) or refused
    (nothing taken: a bad checksum or header, anywhere) exactly as the Python does; a length
    the Python's ``struct`` refuses with an error is handed back to it (NotImplemented)."""
    from robot_daemon.bus.bulk_receive import _take_whole_py

    rng = random.Random(42)
    taken = refused = 0
    for i in range(20_000):
        plan, whole = _bulk_answer(rng, i % 8)
        got_data: dict[int, bytes] = {99: b"kept"}
        got_errors: dict[int, int] = {}
        took = compiled.take_whole(whole, plan.ids, plan.lengths, got_data, got_errors)  # type: ignore[union-attr]
        if i % 8 in (6, 7):
            assert took is NotImplemented
            with pytest.raises(struct.error):
                _take_whole_py(plan, whole, {}, {})
            continue
        want_data: dict[int, bytes] = {99: b"kept"}
        want_errors: dict[int, int] = {}
        assert took is _take_whole_py(plan, whole, want_data, want_errors)
        assert list(got_data.items()) == list(want_data.items())
        assert list(got_errors.items()) == list(want_errors.items())
        taken += took
        refused += not took
    assert taken > 2_000 and refused > 10_000
    for odd in ((bytearray(whole), plan.ids, plan.lengths, {}, {}),
                (whole, list(plan.ids), plan.lengths, {}, {}),
                (whole, plan.ids, plan.lengths[:-1], {}, {}),
                (whole, (1.0,) * len(plan.ids), plan.lengths, {}, {}),
                (whole, (300,) * len(plan.ids), plan.lengths, {}, {})):
        assert compiled.take_whole(*odd) is NotImplemented  # type: ignore[union-attr]


def test_take_run_takes_what_the_reply_by_reply_loop_takes() -> None:
    """The bulk read's replies taken one after another from wherever the receive is (a
    reply's start, its place in the order) in whatever has arrived (cut anywhere, a reply or
    a byte short or over, faults anywhere): the same data, error bits, place, byte and
    verdict as the Python loop (_take_run_py); what it does not take is handed back."""
    from robot_daemon.bus.bulk_receive import _take_run_py

    rng = random.Random(47)
    verdicts: set[tuple[bool, bool]] = set()
    for i in range(20_000):
        plan, whole = _bulk_answer(rng, i % 8)
        n = len(plan.ids)
        due = rng.randrange(n + 1) if rng.random() < 0.7 else 0
        pos = sum(plan.lengths[:due]) + 6 * due
        if rng.random() < 0.1:  # a position that is not a reply's start
            pos = rng.randrange(len(whole) + 1)
        cut = rng.randrange(min(pos, len(whole)), len(whole) + 1)
        buf = whole[:cut] if rng.random() < 0.6 else whole
        results = []
        for take in (compiled.take_run, None):  # type: ignore[union-attr]
            data: dict[int, bytes] = {99: b"kept"}
            errors: dict[int, int] = {}
            if take is not None:
                got = take(buf, pos, due, plan.ids, plan.lengths, data, errors)
            else:
                got = _take_run_py(plan, buf, pos, due, data, errors)
            results.append((got, list(data.items()), list(errors.items())))
        assert results[0] == results[1]
        verdicts.add((results[0][0][2], results[0][0][0] == n))
    assert verdicts == {(True, True), (True, False), (False, False)}
    plan, whole = _bulk_answer(rng, 0)
    ok = (whole, 0, 0, plan.ids, plan.lengths, {}, {})
    assert compiled.take_run(*ok)[2] is True  # type: ignore[union-attr]
    for at, odd in ((0, bytearray(whole)), (1, -1), (2, -1),
                    (2, len(plan.ids) + 1), (2, 1.0), (1, 2**70), (3, list(plan.ids)),
                    (4, plan.lengths[:-1]), (3, (300,) * len(plan.ids)),
                    (4, (254,) * len(plan.ids)), (5, [])):
        args = list(ok)
        args[at] = odd
        assert compiled.take_run(*args) is NotImplemented  # type: ignore[union-attr]


def _servo_state(rng: random.Random) -> Any:
    from robot_daemon.bus.state import ServoState

    st = ServoState()
    for name in ("position", "speed", "load", "misses"):
        getattr(st, name)[:] = [rng.randrange(0, 5000) for _ in range(21)]
    return st


def test_apply_fast_writes_what_the_python_writes(monkeypatch: pytest.MonkeyPatch) -> None:
    """The fast servos' replies into the state's arrays (position, speed, load; misses 0), by
    the compiled path and by numpy, from the same random replies: the same arrays after; a
    reply missing, short or not bytes leaves everything to the Python, nothing written."""
    import numpy as np

    import robot_daemon.bus.sensor_read as sensor_read
    from robot_daemon.bus.bulk_receive import BulkResult

    rng = random.Random(43)
    for _ in range(500):
        fast = sorted(rng.sample(range(1, 21), rng.randrange(1, 21)))
        if rng.random() < 0.5:
            fast = list(range(fast[0], fast[0] + len(fast)))
        at = (slice(fast[0], fast[0] + len(fast)) if fast == list(range(fast[0], fast[-1] + 1))
              else np.array(fast, np.intp))
        pick = itemgetter(*fast) if len(fast) > 1 else (lambda d, f=fast: [d[j] for j in f])
        layout = sensor_read._Layout([], fast, at, pick)
        res = BulkResult(data={j: rng.randbytes(6) for j in fast})
        seed = rng.random()
        states = []
        for use in (compiled, None):
            monkeypatch.setattr(sensor_read, "_compiled", use)
            st = _servo_state(random.Random(seed))
            reader = object.__new__(sensor_read.SensorReader)
            reader.state, reader._alarmed = st, set()
            reader._apply_fast(layout, res, True)
            states.append([getattr(st, n).tolist() for n in ("position", "speed", "load",
                                                            "misses")])
        assert states[0] == states[1]
    st = _servo_state(rng)
    before = [a.copy() for a in (st.position, st.speed, st.load, st.misses)]
    args = (st.position, st.speed, st.load, st.misses, 0, 1, 2, 6)
    for data, fast in (({1: b"\x00" * 6}, [1, 2]), ({1: b"\x00" * 5}, [1]),
                       ({1: bytearray(6)}, [1]), ({21: b"\x00" * 6}, [21]),
                       ({1: b"\x00" * 6}, (1,)), ({-1: b"\x00" * 6}, [-1])):
        assert compiled.apply_fast(data, fast, *args) is NotImplemented  # type: ignore[union-attr]
    assert compiled.apply_fast({1: b"\0" * 6}, [1], st.position, st.speed, st.load,  # type: ignore[union-attr]
                               st.misses.astype(float), 0, 1, 2, 6) is NotImplemented
    assert all((a == b).all() for a, b in zip(before, (st.position, st.speed, st.load,
                                                        st.misses), strict=True))


def test_joint_arrays_give_the_bits_of_numpy() -> None:
    """The frame's joint angles, speeds and loads from raw words (Calibration.joint_arrays)
    compiled and in numpy (joint_arrays_py): the same bits over every word of a servo's range
    and beyond, both directions and random offsets."""
    import numpy as np

    import robot_daemon.bus.calibration as calibration
    from config.loader import load_all, robot_from_dict

    cal = calibration.Calibration(robot_from_dict(load_all()["robot"]))
    rng = random.Random(44)
    for jid in range(1, 21):
        cal.set_offset(jid, rng.uniform(-30, 30))
    words = [[rng.randrange(-5000, 70000) for _ in range(21)] for _ in range(400)]
    words += [list(range(start, start + 21)) for start in range(0, 4096 + 21, 21)]
    for raw in words:
        arrays = [np.array(raw), np.array(raw[::-1]), np.array(raw[3:] + raw[:3])]
        got = cal.joint_arrays(*arrays)
        want = cal.joint_arrays_py(*arrays)
        assert _bits([a.tolist() for a in got]) == _bits([a.tolist() for a in want])
    ints = np.zeros(21, int)
    tables = (units.SPEED_RAD_S_TABLE, units.LOAD_FRACTION_TABLE)
    ok = (ints, ints, ints, cal.sign, cal.offset, *tables, units.RAD_PER_UNIT, 2048,
          np.empty((3, 21)))
    assert compiled.joint_arrays(*ok) is True  # type: ignore[union-attr]
    for at, odd in ((0, ints.astype(float)), (3, cal.sign.astype(np.float32)),
                    (9, np.empty((3, 20))), (9, np.empty((3, 21)).T), (5, tables[0][:100]),
                    (0, np.zeros(20, int)), (7, 1), (0, [0] * 21)):
        args = list(ok)
        args[at] = odd
        assert compiled.joint_arrays(*args) is NotImplemented  # type: ignore[union-attr]


def test_walk_pose_gives_the_python_s_goals(monkeypatch: pytest.MonkeyPatch) -> None:
    """The walk's pose compiled whole (gait._walk_pose: the feet's and pelvis's moves, both
    legs' IK, the arms, the gyro feedback, the limit check) against _pose_py on random gaits,
    clocks, amplitudes, gyro readings and parameters (ints among them): the same goals to the
    bit and in the same key order, the same None, the same filtered gyro kept."""
    import dataclasses

    import numpy as np

    from config.loader import load_all, robot_from_dict
    from robot_daemon.frames import JointFrame
    from robot_daemon.motion.walking import gait
    from robot_daemon.motion.walking.params import WalkParams

    assert gait._walk_pose is not None
    robot = robot_from_dict(load_all()["robot"])
    manager = type("Manager", (), {"robot": robot})()
    rng = random.Random(45)
    ranges = {f.name: f.metadata.get("range") for f in dataclasses.fields(WalkParams)}
    outcomes = {"goals": 0, "none": 0}
    for i in range(20_000):
        p = WalkParams()
        for name, span in ranges.items():
            if span is not None and rng.random() < 0.5:
                lo, hi = span
                value: Any = rng.uniform(lo, hi) * (1.3 if i % 7 == 0 else 1.0)
                setattr(p, name, round(value) if rng.random() < 0.2 else value)
        p.balance_enable = rng.random() < 0.8
        walk = gait.WalkingModule(p)
        walk.manager = manager if rng.random() < 0.9 else None  # type: ignore[assignment]
        walk.time_ms = rng.choice([0.0, walk.ssp_start_l, walk.ssp_end_r, walk.period,
                                   rng.uniform(-10, walk.period + 10)])
        walk.latched = [rng.uniform(-60, 60) * rng.choice([0, 1, 1]) for _ in range(3)]
        walk._gyro_f = [rng.uniform(-50, 50), rng.choice([0, rng.uniform(-50, 50)])]
        frame = JointFrame(tick=i, time=0.0, dt=rng.choice([0.008, 0.016, rng.uniform(0, 0.05)]))
        frame.gyro_raw = np.array([rng.randrange(0, 1024) for _ in range(3)])
        frame.gyro_centre = rng.choice([np.full(3, 512.0), np.array([500.5, 515.25, 512.0])])
        frame.imu_valid = rng.random() < 0.9
        balance = rng.random() < 0.8
        results = []
        for use in (gait._walk_pose, None):
            monkeypatch.setattr(gait, "_walk_pose", use)
            saved = list(walk._gyro_f)
            try:
                goals = walk._pose(frame, balance)
                results.append((None if goals is None else
                                [(j, v.hex()) for j, v in goals.items()],
                                [float(v).hex() for v in walk._gyro_f]))
            except (ZeroDivisionError, ValueError) as exc:  # the Python's, either way
                results.append(repr(exc))
            walk._gyro_f = saved
        assert results[0] == results[1], (i, vars(p))
        outcomes["none" if results[0][0] is None else "goals"] += 1
    assert outcomes["goals"] > 10_000 and outcomes["none"] > 500


def test_snapshot_lists_are_the_python_s(monkeypatch: pytest.MonkeyPatch) -> None:
    """The tick's snapshot (engine/snapshot.take) from one compiled call against take_py (each
    array's tolist, the goals through positions_list): the same fields, types and bits, from
    random servo states, frames and offsets; what it does not take is the Python's."""
    import numpy as np

    from config.loader import load_all, robot_from_dict
    from robot_daemon.bus.robot_bus import RobotBus
    from robot_daemon.engine import snapshot

    settings = load_all()
    bus = RobotBus("none", robot_from_dict(settings["robot"]), settings, lambda *a, **k: None)
    rng = random.Random(46)
    st = bus.state

    def typed(snap: Any) -> list[Any]:
        return [(type(v).__name__, _bits(v) if isinstance(v, list | float) else v)
                for v in snap]

    for i in range(300):
        for jid in range(1, 21):
            bus.calibration.set_offset(jid, rng.uniform(-30, 30))
        for name in ("position", "speed", "load", "goal", "alarm", "misses"):
            getattr(st, name)[:] = [rng.randrange(-100, 5000) for _ in range(21)]
        for name in ("temperature", "voltage"):
            getattr(st, name)[:] = [rng.uniform(0, 90) for _ in range(21)]
        for name in ("torque", "online"):
            getattr(st, name)[:] = [rng.random() < 0.8 for _ in range(21)]
        bus.cm730 = rng.randbytes(30)
        bus.cm730_online = rng.random() < 0.8
        frame = bus.frame(i, rng.uniform(0, 100), 0.008)
        got = snapshot.take(bus, frame, 1.5 * i, i, rng.choice(["none", "front"]))
        want = snapshot.take_py(bus, frame, 1.5 * i, i, got.fall)
        assert typed(got) == typed(want) and type(got) is type(want)
        assert got._asdict().keys() == want._asdict().keys()
    frame.gyro = frame.gyro.astype(np.float32)  # not what it takes: the Python's, the same
    monkeypatch.setattr(snapshot, "take_py", lambda *a: "python")
    assert snapshot.take(bus, frame, 0.0, 0, "none") == "python"
    sign, offset = bus.calibration.angle_columns
    assert compiled.snapshot_lists((st.position,), st.goal.astype(float), sign, offset,  # type: ignore[union-attr]
                                   units.RAD_PER_UNIT, 2048) is NotImplemented


def test_arrays_read_from_their_fields_as_through_their_buffer() -> None:
    """The extension reads numpy's arrays from their fields (configure_arrays, done at import)
    rather than asking each for its buffer: every function gives the same lists and bits, and
    refuses the same arrays (another dtype, byte order, a view with strides, not aligned,
    read-only where it writes, a subclass, two dimensions), as through the buffer."""
    import numpy as np

    from config.loader import load_all, robot_from_dict
    from robot_daemon.bus.calibration import Calibration

    assert hotpath.arrays_direct
    ext: Any = compiled
    sign, offset = Calibration(robot_from_dict(load_all()["robot"])).angle_columns
    goal = np.arange(2000, 2021)

    class Sub(np.ndarray):
        pass

    def make() -> list[Any]:  # fresh each time: the writes below change them
        arrays: list[Any] = []
        for dt in (np.float64, np.bool_, np.int_, np.intc, np.longlong, np.intp, np.int16,
                   np.uint8, np.float32, ">f8", ">i8"):
            a = np.arange(-10, 11).astype(dt)
            read_only = a.copy()
            read_only.flags.writeable = False
            arrays += [a, a[::2], a[3:], a[:0], a[:1], read_only, a.reshape(3, 7),
                       a.reshape(3, 7).T, a.view(Sub)]
        arrays.append(np.frombuffer(bytes(8 * 21 + 1), np.float64, offset=1))  # not aligned
        arrays.append(np.frombuffer(bytearray(8 * 21 + 1), np.float64, offset=1))
        return arrays

    def reads(a: Any) -> Any:
        lists = ext.snapshot_lists((a,), goal, sign, offset, units.RAD_PER_UNIT, 2048)
        out = [a.copy() for _ in range(4)] if a.ndim == 1 else None
        wrote = (ext.apply_fast({1: b"\x01\x02\x03\x04\x05\x06"}, [1], *out, 0, 1, 2, 6)
                 if out is not None and len(a) > 1 else None)
        view_of = (ext.apply_fast({1: bytes(6)}, [1], a, a, a, a, 0, 1, 2, 6)
                   if a.ndim == 1 and len(a) > 1 else None)  # refused where read-only
        return (_bits(list(lists)) if lists is not NotImplemented else lists,
                wrote, [_bits(o.tolist()) for o in out] if out is not None else None, view_of,
                _bits(a.tolist()))

    direct = [reads(a) for a in make()]
    try:
        assert ext.configure_arrays(np.ndarray, ()) is True  # no dtype read directly
        buffered = [reads(a) for a in make()]
    finally:
        assert hotpath._read_arrays_directly(ext)
    assert direct == buffered
    assert sum(d[0] is NotImplemented for d in direct) > 20  # refusals were among them
    assert sum(d[0] is not NotImplemented for d in direct) > 20
    with pytest.raises(TypeError):
        ext.configure_arrays(np.ndarray)
    assert hotpath.arrays_direct


def test_put_ints_writes_what_numpy_writes() -> None:
    """The goals written into the servo state's array (write_targets): put_ints writes the
    ints numpy's ``array[list(at)] = values`` writes, into arrays of numpy's int kinds; what it
    does not take (another dtype, read-only, not one-dimensional, an index numpy would wrap or
    refuse, a value not an int or not fitting) is handed back with nothing written."""
    import numpy as np

    ext: Any = compiled
    rng = random.Random(49)
    for _ in range(3_000):
        dt = rng.choice([np.int_, np.intc, np.longlong, np.int32, np.int64])
        size = rng.randrange(1, 30)
        at = tuple(rng.randrange(size) for _ in range(rng.randrange(0, 25)))
        values = [rng.randrange(-5000, 70000) for _ in at]
        got = np.arange(size, dtype=dt)
        want = got.copy()
        assert ext.put_ints(got, at, values) is True
        want[list(at)] = values
        assert got.tolist() == want.tolist()
    a = np.arange(21)
    ok = (a, (1, 2), [3, 4])
    read_only = a.copy()
    read_only.flags.writeable = False
    for k, odd in ((0, a.astype(float)), (0, a.astype(np.int16)), (0, read_only),
                   (0, a.reshape(3, 7)), (0, a[::2]), (0, a.tolist()), (1, [1, 2]),
                   (1, (1, -1)), (1, (1, 21)), (1, (1, 2.0)), (1, (1,)), (2, (3, 4)),
                   (2, [3, 4.0]), (2, [3, True]), (2, [3, 2**63]), (2, [3, -(2**63) - 1])):
        args = list(ok)
        args[k] = odd
        before = a.copy()
        assert ext.put_ints(*args) is NotImplemented
        assert (a == before).all()
    small = np.zeros(3, np.int32)
    assert ext.put_ints(small, (0,), [2**31]) is NotImplemented and small.tolist() == [0, 0, 0]


def test_put_row_writes_what_numpy_writes(monkeypatch: pytest.MonkeyPatch) -> None:
    """A servo's slow block into the state (SensorReader.apply_slow): put_row writes into each
    array the value numpy's ``a[j] = v`` writes, compiled or one by one, over random blocks;
    an array or value it does not take (another dtype or kind, read-only, an index outside,
    a value not fitting) is handed back with nothing written."""
    import numpy as np

    import robot_daemon.bus.sensor_read as sensor_read

    ext: Any = compiled
    rng = random.Random(50)
    for i in range(2_000):
        block = rng.randbytes(sensor_read.SLOW_LENGTH)
        jid, error = rng.randrange(1, 21), 0
        states = []
        for use in (compiled, None):
            monkeypatch.setattr(sensor_read, "_compiled", use)
            st = _servo_state(random.Random(i))
            reader = object.__new__(sensor_read.SensorReader)
            reader.state, reader._alarmed, reader.emit = st, set(), lambda *a, **k: None
            reader.apply_slow(jid, block, error)
            states.append([_bits(getattr(st, n).tolist()) for n in (
                "torque_limit", "torque", "goal", "position", "speed", "load", "voltage",
                "temperature", "alarm")])
        assert states[0] == states[1]
    ints, floats, bools = np.zeros(21, int), np.zeros(21), np.zeros(21, bool)
    ok = ((ints, floats, bools), 3, (7, 1.5, True))
    assert ext.put_row(*ok) is True and (ints[3], floats[3], bools[3]) == (7, 1.5, True)
    read_only = ints.copy()
    read_only.flags.writeable = False
    for k, odd in ((0, [ints, floats, bools]), (0, (ints.astype(np.int16), floats, bools)),
                   (0, (read_only, floats, bools)), (0, (ints.reshape(3, 7), floats, bools)),
                   (0, (ints, floats[::2], bools)), (1, 21), (1, -1), (1, 3.0),
                   (2, (7, 1, True)), (2, (7.0, 1.5, True)), (2, (7, 1.5, 1)),
                   (2, (2**63, 1.5, True)), (2, (7, 1.5)), (2, [7, 1.5, True])):
        args = list(ok)
        args[k] = odd
        before = [a.copy() for a in (ints, floats, bools)]
        assert ext.put_row(*args) is NotImplemented
        assert all((a == b).all() for a, b in zip(before, (ints, floats, bools), strict=True))


@pytest.mark.parametrize("dps", [500, 1000.0, 250, 333.3])
def test_imu_lists_give_the_bits_of_the_python(dps: float) -> None:
    """The frame's IMU in SI units (state.imu_si): imu_lists against imu_lists_py, the same
    bits over every count of the CM-730's range and beyond, with the robot's axis signs;
    what it does not take (not lists of three ints, signs not ints, a float count) is the
    Python's."""
    from robot_daemon.bus import state

    ext: Any = compiled
    f = 2 * dps / units.IMU_MAX
    consts = (units.IMU_CENTER, f, math.pi, units.ACCEL_G_PER_COUNT, units.GRAVITY)
    rng = random.Random(51)
    counts = [[r, (r * 7) % 1100 - 20, 1023 - r] for r in range(-20, 1100)]
    counts += [[rng.randrange(-(2**40), 2**40) for _ in range(3)] for _ in range(500)]
    for gyro_raw in counts:
        accel_raw = gyro_raw[::-1]
        got = ext.imu_lists(gyro_raw, accel_raw, state._GYRO_SIGN, state._ACCEL_SIGN, *consts)
        want = state.imu_lists_py(gyro_raw, accel_raw, f)
        assert _bits(list(got)) == _bits(list(want))
        signs = (1, -1, -1)
        got = ext.imu_lists(gyro_raw, accel_raw, signs, signs, *consts)
        assert got is not NotImplemented
    ok = ([1, 2, 3], [4, 5, 6], (1, 1, 1), (1, 1, 1), *consts)
    for at, odd in ((0, (1, 2, 3)), (0, [1, 2]), (0, [1, 2, 3.0]), (1, [4, 5, 2**41]),
                    (2, [1, 1, 1]), (2, (1, 1, 1.0)), (3, (1, 1)), (4, 512.0), (5, 1),
                    (8, 9)):
        args = list(ok)
        args[at] = odd
        assert ext.imu_lists(*args) is NotImplemented


@pytest.mark.parametrize("dps", [500, 2000.0])
def test_imu_arrays_are_the_python_s(dps: float) -> None:
    """The frame's four IMU arrays (state.imu_arrays) compiled and as imu_raw, imu_si and
    np.array make them (imu_arrays_py): the same dtypes and bits from random CM-730 blocks and
    every count; a block too short is refused as the Python's struct refuses it, an empty one
    is the centre; arrays or offsets it does not take leave everything to the Python."""
    import numpy as np

    from robot_daemon.bus import state

    ext: Any = compiled
    rng = random.Random(52)
    blocks = [rng.randbytes(rng.randrange(state._IMU_NEED, 40)) for _ in range(3_000)]
    blocks += [bytes([v & 0xFF, v >> 8] * 20) for v in range(0, 65536, 97)]
    for block in [*blocks, b""]:
        got, want = state.imu_arrays(block, dps), state.imu_arrays_py(block, dps)
        assert [a.dtype for a in got] == [a.dtype for a in want]
        assert _bits([a.tolist() for a in got]) == _bits([a.tolist() for a in want])
    with pytest.raises(struct.error):
        state.imu_arrays(bytes(state._IMU_NEED - 1), dps)
    out = [np.zeros(3, int), np.zeros(3, int), np.zeros(3), np.zeros(3)]
    consts = (state._GYRO_SIGN, state._ACCEL_SIGN, units.IMU_CENTER, 1.0, math.pi,
              units.ACCEL_G_PER_COUNT, units.GRAVITY)
    ok = [bytes(30), 26, state._GYRO_BYTES, state._ACCEL_BYTES, *consts, *out]
    assert ext.imu_arrays(*ok) is True
    read_only = np.zeros(3)
    read_only.flags.writeable = False
    for at, odd in ((0, bytearray(30)), (1, 31), (1, -1), (2, (14, 16, 29)), (2, (14, 16)),
                    (2, (14, 16, -1)), (3, [20, 22, 24]), (11, np.zeros(3)),
                    (12, np.zeros(4, int)), (13, np.zeros(3, np.float32)), (14, read_only),
                    (14, np.zeros((1, 3))), (6, 512.0)):
        args = list(ok)
        args[at] = odd
        for a in out:
            a[:] = 7
        assert ext.imu_arrays(*args) is NotImplemented
        assert all((a == 7).all() for a in out)
