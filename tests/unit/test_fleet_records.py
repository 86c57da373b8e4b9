"""Discovery records from status messages (clients/fleet.py): what `darwin list` prints."""

from __future__ import annotations

from clients.fleet import RobotRecord, record_from_status
from schemas.messages import Status


def test_a_record_takes_its_fields_from_the_status() -> None:
    status = Status(
        state="degraded",
        robot="op2",
        lease={"client": "c0ffee", "name": "ana", "since": 1.0},
        voltage=11.4,
        alarms=[{"id": 7, "bits": 32}],
        loop={"tick_ms": 8.0, "period_p50_ms": 8.0},
        network={"endpoint": "tcp/10.0.0.2:7447", "router": "tcp/10.0.0.2:7447", "listen": []},
    )
    r = record_from_status("op2", status)
    assert r == RobotRecord(
        "op2",
        "tcp/10.0.0.2:7447",
        "degraded",
        "ana",
        11.4,
        [{"id": 7, "bits": 32}],
        125.0,
        version="unknown",
        protocol="1.0",
    )
    assert r.line() == (
        "op2: tcp/10.0.0.2:7447  (degraded; lease ana; battery 11.4 V; hottest ?; "
        "alarms id 7 bits 32; loop 125 Hz; daemon unknown protocol 1.0)"
    )


def test_a_live_robot_without_a_status_yet_is_listed_as_unknown() -> None:
    r = record_from_status("op3", None)
    assert (r.name, r.state, r.battery, r.loop_hz, r.lease_holder) == (
        "op3", "unknown", None, None, None
    )
    assert r.line() == (
        "op3: ?  (unknown; lease free; battery ?; hottest ?; alarms none; loop ?; daemon ? "
        "protocol ?)"
    )
    assert r.to_dict()["alarms"] == []
