"""The ball follower's decisions, frame by frame, with nothing mounted or connected."""

from __future__ import annotations

import pytest

from robot_daemon.motion.ball.follower import Follower
from robot_daemon.motion.ball.settings import FollowerSettings, HeadSettings

HEAD = HeadSettings()
AT_BOTTOM = HEAD.tilt_min_deg
BALL_LOW = FollowerSettings().kick_top_deg - 1.0  # below the image centre enough to stop


def settle(follower: Follower, pan: float, pan_err: float) -> int:
    """Feed steady frames of a ball at the robot's feet until the follower kicks."""
    for _ in range(100):
        cmd = follower.update(True, BALL_LOW, pan, AT_BOTTOM, pan_err)
        assert not cmd.walk
        if cmd.kick:
            return cmd.kick
    raise AssertionError("the follower never kicked")


@pytest.mark.parametrize(
    ("pan", "pan_err", "foot"),
    [
        pytest.param(10.0, 0.0, 1, id="ball-left-left-foot"),
        pytest.param(-10.0, 0.0, -1, id="ball-right-right-foot"),
        # The head lags the ball: it still points 1° left while the ball is 3.6° right of the
        # image centre, so the ball lies right of the robot and the right foot must kick.
        pytest.param(1.0, -3.6, -1, id="head-lags-ball-right"),
        pytest.param(-1.0, 3.6, 1, id="head-lags-ball-left"),
    ],
)
def test_kicks_with_the_foot_on_the_balls_side(pan: float, pan_err: float, foot: int) -> None:
    assert settle(Follower(FollowerSettings(), HEAD), pan, pan_err) == foot


def test_losing_the_ball_restarts_the_steady_count() -> None:
    follower = Follower(FollowerSettings(), HEAD)

    def frames_to_kick() -> int:
        for n in range(1, 100):
            if follower.update(True, BALL_LOW, 0.0, AT_BOTTOM, 2.0).kick:
                return n
        raise AssertionError("the follower never kicked")

    steady = frames_to_kick()
    assert steady > 1  # never on the first frame: the ball must hold still first
    follower.reset()
    for _ in range(steady - 1):
        assert not follower.update(True, BALL_LOW, 0.0, AT_BOTTOM, 2.0).kick
    follower.update(False, 0.0, 0.0, AT_BOTTOM)  # one frame without the ball
    assert frames_to_kick() == steady


def test_walks_forward_while_the_head_still_looks_up() -> None:
    follower = Follower(FollowerSettings(), HEAD)
    first = follower.update(True, 0.0, 0.0, 20.0)
    assert first.walk and first.step == 0.0  # the walk starts from standing
    later = [follower.update(True, 0.0, 0.0, 20.0) for _ in range(5)]
    assert all(c.walk and c.kick == 0 for c in later)
    assert later[-1].step > later[0].step  # ramps by unit_step_mm per frame


def test_turns_in_place_when_the_ball_is_far_to_the_side() -> None:
    follower = Follower(FollowerSettings(), HEAD)
    follower.update(True, 0.0, 50.0, 0.0)
    cmd = follower.update(True, 0.0, 50.0, 0.0)
    assert cmd.walk and cmd.step == 0.0 and cmd.turn > 0.0
