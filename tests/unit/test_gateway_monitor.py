"""Monitor messages (only requested streams, only changed values), limits and settings."""

from __future__ import annotations

import base64
import logging
import math

import pytest

from gateway.limits import RateLimitedLog, TokenBucket
from gateway.monitor import (
    MonitorView,
    Snapshot,
    accelerometer_from_imu,
    camera_from_frame,
    gyroscope_from_imu,
    motors_from_joints,
)
from gateway.settings import load_settings
from schemas.errors import ConfigError
from schemas.messages import CameraFrame, Imu, Joints


def joints(positions: list[float]) -> Joints:
    n = len(positions)
    return Joints(
        id=list(range(1, n + 1)),
        name=[f"j{i}" for i in range(1, n + 1)],
        position=[math.radians(p) for p in positions],  # degrees given, radians on the wire
        goal=[0.0] * n,
        velocity=[0.5] * n,
        load=[-0.25] * n,
        temperature=[40.0] * n,
        voltage=[12.0] * n,
        torque_enabled=[True] * n,
        online=[True] * n,
        alarm=[0] * n,
    )


def snap(positions: list[float], accel: list[float] | None = None, seq: int = 1) -> Snapshot:
    imu = Imu(
        gyro=[0.1, 0.0, -0.1], accel=accel or [0.0, 0.0, 9.81], gyro_raw=[0] * 3, accel_raw=[0] * 3
    )
    frame = CameraFrame(jpeg=b"\xff\xd8jpeg" + bytes([seq]), width=2, height=2, seq=seq)
    return Snapshot(
        motors=motors_from_joints(joints(positions)),
        accelerometer=accelerometer_from_imu(imu),
        gyroscope=gyroscope_from_imu(imu),
        camera=camera_from_frame(frame),
    )


def test_motor_tuple_is_id_position_speed_load_torque() -> None:
    m = motors_from_joints(joints([20.04, -45.0]))
    assert m[1] == (1, 20.0, 28.6, -25.0, 1)
    assert m[2][1] == -45.0


def test_only_requested_streams_and_only_changes() -> None:
    view = MonitorView()
    assert view.build(snap([1.0, 2.0])) == {"monitor": {}}
    view.update({"motors": True})
    first = view.build(snap([1.0, 2.0]))["monitor"]
    assert list(first) == ["motors"]
    assert [m["motor"][0] for m in first["motors"]] == [1, 2]
    assert view.build(snap([1.0, 2.0])) == {"monitor": {}}
    changed = view.build(snap([1.0, 3.0]))["monitor"]
    assert changed["motors"] == [{"motor": [2, 3.0, 28.6, -25.0, 1]}]
    # Noise below the shown resolution is not a change.
    assert view.build(snap([1.01, 3.02])) == {"monitor": {}}


def test_turning_a_stream_on_again_sends_it_whole() -> None:
    view = MonitorView()
    view.update({"accelerometer": True, "gyroscope": True, "camera": True})
    first = view.build(snap([0.0]))["monitor"]
    assert set(first) == {"accelerometer", "gyroscope", "camera"}
    assert base64.b64decode(first["camera"]).startswith(b"\xff\xd8")
    assert view.build(snap([0.0])) == {"monitor": {}}
    assert "camera" in view.build(snap([0.0], seq=2))["monitor"]
    view.update({"accelerometer": False})
    view.update({"accelerometer": True})
    assert list(view.build(snap([0.0], seq=2))["monitor"]) == ["accelerometer"]
    view.update({"accelerometer": False, "gyroscope": False, "camera": False})
    assert not view.active


def test_camera_can_be_left_out_for_a_client_that_cannot_carry_it() -> None:
    view = MonitorView()
    view.update({"camera": True})
    assert view.build(snap([0.0]), camera=False) == {"monitor": {}}
    assert "camera" in view.build(snap([0.0]))["monitor"]


def test_token_bucket_allows_a_burst_then_the_rate() -> None:
    now = [0.0]
    bucket = TokenBucket(rate=10.0, burst=3, clock=lambda: now[0])
    assert [bucket.take() for _ in range(3)] == [0.0, 0.0, 0.0]
    assert bucket.take() == pytest.approx(0.1)
    now[0] = 1.0
    assert bucket.take() == 0.0


def test_rate_limited_log_holds_back_repeats(caplog: pytest.LogCaptureFixture) -> None:
    now = [0.0]
    ratelog = RateLimitedLog(logging.getLogger("gw-test"), 5.0, clock=lambda: now[0])
    burst = RateLimitedLog(logging.getLogger("gw-test"), 5.0, burst=3, clock=lambda: now[0])
    with caplog.at_level(logging.INFO, logger="gw-test"):
        assert ratelog("bad", logging.INFO, "bad input from %s", "a")
        assert not ratelog("bad", logging.INFO, "bad input from %s", "b")
        assert not ratelog("bad", logging.INFO, "bad input from %s", "c")
        assert ratelog("other", logging.INFO, "another kind")
        assert [burst("c", logging.INFO, "connect") for _ in range(5)] == [1, 1, 1, 0, 0]
        now[0] = 6.0
        assert ratelog("bad", logging.INFO, "bad input from %s", "d")
        assert burst("c", logging.INFO, "connect")
    assert len(caplog.records) == 7
    assert "2 similar lines held back" in caplog.records[5].getMessage()
    assert "2 similar lines held back" in caplog.records[6].getMessage()


def test_settings_load_and_reject_bad_values(tmp_path) -> None:
    s = load_settings()
    assert s.host_port == ("127.0.0.1", 9000)
    assert s.walk.x_mps_per_unit > 0
    user = tmp_path / "user.toml"
    user.write_text(
        '[gateway]\nlisten = "0.0.0.0:0"\nmax_rate = 5\n[gateway.walk]\nx_mps_per_unit = 0.01\n'
    )
    s = load_settings(user)
    assert s.host_port == ("0.0.0.0", 0) and s.max_rate == 5.0 and s.walk.x_mps_per_unit == 0.01
    user.write_text('[gateway]\nlisten = "nowhere"\n')
    with pytest.raises(ConfigError, match="not HOST:PORT"):
        load_settings(user)
    user.write_text('[gateway]\nmonitor_period = "fast"\n')
    with pytest.raises(ConfigError, match="monitor_period = 'fast' should be a number"):
        load_settings(user)
    user.write_text("[gateway]\nspeed = 1\n")
    with pytest.raises(ConfigError, match=r"\[gateway\] has an unknown setting 'speed' \(nearest"):
        load_settings(user)
    user.write_text("[gateway.walk]\nx_mps_per_unti = 0.01\n")
    near = r"\[gateway.walk\] .* 'x_mps_per_unti' \(nearest known: 'x_mps_per_unit'\)"
    with pytest.raises(ConfigError, match=near):
        load_settings(user)
