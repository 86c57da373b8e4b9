"""The joints and IMU bytes the loop sends from a packed layout (schemas/packed.py) are the bytes
``encode`` gives for the same message: one definition of each message, two ways to pack it."""

from __future__ import annotations

import math
import random

import pytest

from config.loader import load_all, robot_from_dict
from robot_daemon.engine.broadcast import JointsEncoder, imu_message, imu_payload
from robot_daemon.engine.snapshot import TickSnapshot, take
from robot_daemon.frames import N_SLOTS
from schemas.messages import Imu, Joints, decode, encode
from schemas.packed import Prepacked


def snapshot(rng: random.Random, tick: int, alarm_max: int = 127) -> TickSnapshot:
    def floats(scale: float, n: int = N_SLOTS) -> list[float]:
        return [rng.uniform(-scale, scale) for _ in range(n)]

    return TickSnapshot(
        tick=tick, stamp=rng.uniform(1.7e9, 1.8e9), time=rng.uniform(0, 1e4),
        position=floats(math.pi), velocity=floats(6.0), load=floats(1.0), goal=floats(math.pi),
        temperature=[float(rng.randrange(20, 80)) for _ in range(N_SLOTS)],
        voltage=floats(12.0),
        torque=[rng.random() < 0.8 for _ in range(N_SLOTS)],
        online=[rng.random() < 0.9 for _ in range(N_SLOTS)],
        alarm=[rng.choice([0, 0, 0, 4, 32, alarm_max]) for _ in range(N_SLOTS)],
        gyro=floats(5.0, 3), accel=floats(20.0, 3),
        gyro_raw=[rng.randrange(1024) for _ in range(3)],
        accel_raw=[rng.randrange(1024) for _ in range(3)],
        cm730=bytes(30), cm730_online=True, fall=rng.choice(["none", "forward", "backward"]),
    )


@pytest.fixture(autouse=True, params=["compiled", "msgpack"])
def packer(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """Each test with the compiled packer (where it is built) and with msgpack's."""
    import robot_daemon.engine.broadcast as broadcast

    if request.param == "msgpack":
        monkeypatch.setattr(broadcast, "_compiled", None)
    elif broadcast._compiled is None:
        pytest.skip("the compiled hot path is not built")
    return str(request.param)


@pytest.fixture(scope="module")
def joints() -> JointsEncoder:
    return JointsEncoder(robot_from_dict(load_all()["robot"]))


@pytest.mark.parametrize("tick", [0, 1, 127, 128, 255, 256, 65535, 65536, 2**32 + 5])
def test_joints_bytes_equal_encode(joints: JointsEncoder, tick: int) -> None:
    rng = random.Random(tick)
    for _ in range(20):
        snap = snapshot(rng, tick)
        packed = joints.encode(snap)
        assert packed == encode(joints.message(snap))
        back = decode(packed, Joints)
        assert back.tick == tick and back.position == joints.message(snap).position


def test_joints_alarm_of_any_size(joints: JointsEncoder) -> None:
    snap = snapshot(random.Random(3), 9, alarm_max=200)
    assert joints.encode(snap) == encode(joints.message(snap))


def test_snapshot_of_a_tick_matches_the_bus(joints: JointsEncoder) -> None:
    """take() copies what the bus holds, converted as the bus's own calibration does."""
    from tests.fixtures.sim_rig import SimRig

    rig = SimRig(seed=2)
    rig.run(0.1)
    frame = rig.frame()
    snap = take(rig.bus, frame, 5.0, rig.tick, "none")
    assert snap.goal == rig.bus.calibration.positions(rig.bus.state.goal).tolist()
    assert snap.position == frame.position.tolist()
    msg = joints.message(snap)
    assert msg.position == frame.position[1:21].tolist()  # radians, the only unit on the wire
    assert msg.online == rig.bus.state.online[1:21].tolist()
    rig.bus.state.online[3] = False  # the next tick's write does not reach the snapshot
    assert snap.online[3]


@pytest.mark.parametrize("seed", range(10))
def test_imu_bytes_equal_encode(seed: int) -> None:
    snap = snapshot(random.Random(seed), seed * 1000)
    assert imu_payload(snap) == encode(imu_message(snap))
    assert decode(imu_payload(snap), Imu).gyro_raw == snap.gyro_raw


def test_a_layout_packs_what_encode_packs() -> None:
    layout = Prepacked(Imu, {"fall": "none"})
    assert layout.fields == ("gyro", "accel", "gyro_raw", "accel_raw", "stamp", "tick")
    msg = Imu(gyro=[1.5, -2.0, 0.0], accel=[0.0, 0.0, 9.81], gyro_raw=[512, 0, 1023],
              accel_raw=[1, 2, 3], fall="none", stamp=12.5, tick=7)
    out = layout.pack([msg.gyro, msg.accel, msg.gyro_raw, msg.accel_raw, 12.5, 7])
    assert out == encode(msg)
