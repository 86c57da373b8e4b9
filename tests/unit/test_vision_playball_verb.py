"""The ``playball`` verb's checks, on a real motion manager (no daemon, no camera)."""

from __future__ import annotations

import pytest

from robot_daemon.arbiter.registry import MotionContext, Reject, Request, needs_lease
from robot_daemon.arbiter.verbs import ballplay
from schemas.errors import ErrorCode
from tests.fixtures.motion import motion_context


@pytest.fixture
def ctx() -> MotionContext:
    return motion_context()


def call(ctx: MotionContext, **fields) -> dict:
    return ballplay.playball(Request("playball", "c1", "tester", fields), ctx)


def test_start_needs_the_lease_and_stop_does_not() -> None:
    assert needs_lease("playball", {"op": "start"})
    assert not needs_lease("playball", {"op": "stop"})


def test_start_without_a_camera_says_how_to_get_one(ctx: MotionContext) -> None:
    with pytest.raises(Reject) as exc:
        call(ctx, op="start")
    assert exc.value.code == ErrorCode.UNAVAILABLE
    assert "--camera sim" in exc.value.message
    assert ctx.manager.module("ball").phase == "idle"
    assert not ctx.manager.owned_by("ball")


@pytest.mark.parametrize(
    ("fields", "field"),
    [({"op": "dance"}, "op"), ({}, "op"), ({"op": "start", "color": "mauve"}, "color")],
)
def test_bad_fields_are_named(ctx: MotionContext, fields: dict, field: str) -> None:
    with pytest.raises(Reject) as exc:
        call(ctx, **fields)
    assert exc.value.field == field
    assert ctx.manager.module("ball").phase == "idle"


def test_stop_is_always_accepted(ctx: MotionContext) -> None:
    assert call(ctx, op="stop") == {"op": "stop", "phase": "idle"}
