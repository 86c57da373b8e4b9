"""WorldViews: the World message, camera view and image every simulated plant shares."""

from __future__ import annotations

import math

import numpy as np

from robot_daemon.plant.ball import BallState
from robot_daemon.plant.camera_model import CameraPose
from robot_daemon.plant.views import WorldViews
from robot_daemon.plant.world_settings import WorldSettings


class _Plant(WorldViews):
    """A plant that stands still where it is told: only what WorldViews asks for."""

    def __init__(self, ball: BallState | None) -> None:
        super().__init__(WorldSettings(), seed=1)
        self.time = 1.5
        self.ball = ball

    def _robot(self) -> tuple[float, float, float, str]:
        return 1.0, 2.0, 0.5, "forward"

    def _ball_now(self) -> BallState | None:
        return self.ball

    def _camera_pose(self) -> CameraPose:
        # At the robot's place 0.45 m up, looking along +x, level.
        return CameraPose(np.array([1.0, 2.0, 0.45]), np.eye(3))


def test_snapshot_carries_the_plants_pose_fall_ball_and_time() -> None:
    w = _Plant(BallState(4.0, 2.0, 0.5, -0.25)).snapshot()
    assert w.robot == {"x": 1.0, "y": 2.0, "yaw": 0.5}
    assert w.ball == {"x": 4.0, "y": 2.0, "vx": 0.5, "vy": -0.25}
    assert (w.fallen, w.sim_time) == ("forward", 1.5)
    assert _Plant(None).snapshot().ball == {}


def test_camera_view_and_distance_follow_the_ball() -> None:
    plant = _Plant(BallState(4.0, 6.0))
    pose, ball = plant.camera_view()
    assert pose.position.tolist() == [1.0, 2.0, 0.45]
    assert ball is not None and (ball.x, ball.y) == (4.0, 6.0)
    assert ball.radius == plant.settings.ball.radius
    assert plant.ball_distance() == math.hypot(3.0, 4.0)
    plant.ball = None
    assert plant.camera_view()[1] is None
    assert plant.ball_distance() is None


def test_render_shows_the_ball_in_front_of_the_camera() -> None:
    plant = _Plant(None)
    empty = plant.render()
    cam = plant.settings.render.camera
    assert empty.shape == (cam.height, cam.width, 3)
    plant.ball = BallState(3.0, 2.0)
    with_ball = plant.render()
    # The ball is red (BGR: high last channel) where the empty view had none.
    red = (with_ball[..., 2].astype(int) - with_ball[..., 1]) > 80
    red_before = (empty[..., 2].astype(int) - empty[..., 1]) > 80
    assert red.sum() > red_before.sum() + 20


def test_the_renderer_made_at_the_first_frame_draws_as_one_made_with_the_world() -> None:
    """Made on first use (a world nobody watches never loads it), seeded with the world's seed:
    the same frames as a renderer made beside the world with that seed."""
    from robot_daemon.plant.render import Renderer

    plant = _Plant(BallState(3.0, 2.0))
    r = plant.settings.render
    beside = Renderer(
        r.camera, plant.settings.field, noise=r.noise, light_variation=r.light_variation,
        blur=r.blur, seed=1,
    )  # fmt: skip
    for _ in range(2):
        assert np.array_equal(plant.render(), beside.render(*plant.camera_view()))
    assert plant.renderer() is plant.renderer()
