"""The status sub-maps a running daemon publishes carry exactly the keys `schemas` declares, so
clients read declared keys instead of guessing."""

from __future__ import annotations

import typing

from schemas.messages import BusInfo, CameraInfo, LeaseInfo, LoopInfo, Status
from tests.fixtures.system import RunningSystem


def _keys(td: type) -> set[str]:
    return set(typing.get_type_hints(td))


def test_published_status_sub_maps_match_their_declared_types(robot_system: RunningSystem) -> None:
    with robot_system.robot_client(name="contract") as robot:
        robot.acquire()
        try:
            status: Status = robot.wait_for("status", lambda s: s.lease is not None, 20)
        finally:
            robot.release()
    assert set(status.lease or {}) == _keys(LeaseInfo)
    assert set(status.loop) == _keys(LoopInfo)
    assert set(status.bus) <= _keys(BusInfo), set(status.bus) - _keys(BusInfo)
    assert set(status.camera) <= _keys(CameraInfo), set(status.camera) - _keys(CameraInfo)
