"""Ball play closed on the simulator, faster than real time: servo dynamics (the emulator's bus
model), the world (odometry, falls, ball), the daemon's motion modules and the ball finder on
rendered frames step together on a simulated clock (``SimRig``).

The kick pages come from the project's own motion library (what users get) and, where
``shared/data`` holds it, from the stock ROBOTIS file read in place: the same play must work
with both.
"""

from __future__ import annotations

import math

import pytest

from config.loader import load_all
from tests.fixtures.sim_rig import SimRig
from tests.shared_data import STOCK_MOTIONS

LIBRARIES = [
    pytest.param(None, id="project-pages"),
    pytest.param(
        str(STOCK_MOTIONS),
        id="stock-pages",
        marks=pytest.mark.skipif(
            not STOCK_MOTIONS.exists(), reason="needs the stock motion file in shared/data"
        ),
    ),
]


def make_rig(seed: int, search_timeout: float = 40.0, library: str | None = None) -> SimRig:
    settings = load_all()
    if library is not None:
        settings.setdefault("motion", {})["library"] = library
    settings["ballplay"]["tracker"]["search_timeout_s"] = search_timeout
    return SimRig(seed=seed, settings=settings)


def distance(rig: SimRig) -> float:
    d = rig.world.ball_distance()
    assert d is not None
    return d


@pytest.mark.parametrize(
    ("ball", "seed"),
    [
        pytest.param((0.5, 0.1), 1, id="ahead"),
        pytest.param((0.35, 0.45), 2, id="left"),
        pytest.param((0.35, -0.45), 3, id="right"),
        pytest.param((-0.45, 0.1), 4, id="behind"),
    ],
)
@pytest.mark.parametrize("library", LIBRARIES)
def test_finds_approaches_and_kicks_the_ball(
    ball: tuple[float, float], seed: int, library: str | None
) -> None:
    rig = make_rig(seed, library=library)
    rig.world.place_robot(0.0, 0.0, 0.0)
    rig.world.place_ball(*ball)
    rig.run(0.3)
    start = distance(rig)
    phases: list[str] = []

    def watch(r: SimRig) -> bool:
        if not phases or phases[-1] != r.ball_play.phase:
            phases.append(r.ball_play.phase)
        return not r.ball_play.playing

    rig.ball_play.start()
    assert rig.run_until(watch, timeout=60.0), f"still {rig.ball_play.phase} after 60 s"
    rig.run_until(lambda r: r.world.ball.state.speed == 0.0, timeout=10.0)
    assert rig.ball_play.phase == "done", phases
    assert "kicking" in phases and "approaching" in phases
    assert rig.world.falls == 0
    assert rig.world.ball.touches > 0
    assert distance(rig) > start + 0.3, rig.world.snapshot()


def test_without_a_ball_it_searches_turns_and_reports_lost_without_falling() -> None:
    rig = make_rig(5, search_timeout=12.0)
    rig.world.remove_ball()
    rig.run(0.3)
    yaw0 = rig.world.snapshot().robot["yaw"]
    seen: set[str] = set()

    def done(r: SimRig) -> bool:
        seen.add(r.ball_play.phase)
        return not r.ball_play.playing

    rig.ball_play.start()
    assert rig.run_until(done, timeout=20.0)
    assert rig.ball_play.phase == "lost"
    assert seen == {"searching", "lost"}
    assert rig.world.falls == 0
    # The search turned the body to look around, not only the head.
    turned = abs(math.remainder(rig.world.snapshot().robot["yaw"] - yaw0, 2 * math.pi))
    assert turned > math.radians(30)
    assert not any(d.found for d in rig.detections)


def test_the_kick_page_starts_after_the_walk_stopped_and_the_body_stood_still() -> None:
    rig = make_rig(1)
    settle = rig.ball_play.settings.follower.kick_settle_s
    assert settle > 0  # config/ballplay.toml: the page starts from rest, not mid-sway
    rig.world.place_robot(0.0, 0.0, 0.0)
    rig.world.place_ball(0.5, 0.1)
    rig.run(0.3)
    walking, action = rig.manager.get("walking"), rig.manager.get("action")
    seen: dict[str, float] = {}

    def watch(r: SimRig) -> bool:
        if r.ball_play.phase == "kicking":
            if walking.running:
                seen.pop("walk_stopped", None)
            else:
                seen.setdefault("walk_stopped", r.time)
            if action.playing:
                seen.setdefault("page", r.time)
        return "page" in seen or not r.ball_play.playing

    rig.ball_play.start()
    assert rig.run_until(watch, timeout=60.0) and "page" in seen, rig.ball_play.phase
    assert seen["page"] - seen["walk_stopped"] >= settle - 0.01


ROBOT_VISION_HZ = 15.0  # the robot recipe's [ballplay] vision_hz (docs/robot.md, loop-cpu.md)


def test_plays_at_the_robots_vision_rate() -> None:
    """The Atom's vision rate, chosen from the counted cost of a frame (docs/loop-cpu.md): ball
    play still finds, approaches and kicks the ball with half the frames."""
    settings = load_all()
    settings["ballplay"]["vision_hz"] = ROBOT_VISION_HZ
    rig = SimRig(seed=1, settings=settings, vision_fps=ROBOT_VISION_HZ)
    rig.world.place_robot(0.0, 0.0, 0.0)
    rig.world.place_ball(0.5, 0.1)
    rig.run(0.3)
    start = distance(rig)
    rig.ball_play.start()
    assert rig.run_until(lambda r: not r.ball_play.playing, timeout=60.0), rig.ball_play.phase
    rig.run_until(lambda r: r.world.ball.state.speed == 0.0, timeout=10.0)
    assert rig.ball_play.phase == "done"
    assert rig.world.falls == 0 and rig.world.ball.touches > 0
    assert distance(rig) > start + 0.3, rig.world.snapshot()
    seconds = rig.time - 0.3
    assert len(rig.detections) <= seconds * ROBOT_VISION_HZ + 5  # it saw at that rate
