"""The ball finder on rendered frames and on synthetic real-looking photos."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from config.loader import load_section
from robot_daemon.plant.camera_model import CameraModel
from robot_daemon.plant.render import BallView, Renderer, look_at
from robot_daemon.vision.ball_finder import BallFinder, FinderSettings, color_range
from schemas.errors import ConfigError

EYE = np.array([0.0, 0.0, 0.45])


@pytest.fixture(scope="module")
def ballplay() -> dict:
    return load_section("ballplay")


@pytest.fixture(scope="module")
def finder(ballplay: dict) -> BallFinder:
    return BallFinder(FinderSettings.from_config(ballplay))


def render(ball_xy: tuple[float, float] | None, target=(1.0, 0.0, 0.0), seed: int = 1):
    pose = look_at(EYE, np.array(target))
    ball = BallView(ball_xy[0], ball_xy[1], 0.035) if ball_xy else None
    return Renderer(seed=seed).render(pose, ball), pose


def expected_angles(pose, ball_xy) -> tuple[float, float]:
    """Where the ball's centre is, as angles from the optical axis (pixel-linear like the
    framework's law, so compare through the same pinhole model)."""
    cam = CameraModel()
    c = pose.rotation.T @ (np.array([ball_xy[0], ball_xy[1], 0.035]) - pose.position)
    u, v = cam.project(c)
    return (
        (cam.width / 2 - u) * math.radians(58) / cam.width,
        (cam.height / 2 - v) * math.radians(46) / cam.height,
    )


@pytest.mark.parametrize("ball_xy", [(0.8, 0.0), (0.7, 0.25), (0.7, -0.25), (1.6, 0.3)])
def test_finds_the_rendered_ball_where_it_is(finder: BallFinder, ball_xy) -> None:
    img, pose = render(ball_xy)
    det = finder.find(img)
    assert det.found
    pan, tilt = expected_angles(pose, ball_xy)
    assert det.pan_error == pytest.approx(pan, abs=math.radians(1.0))
    assert det.tilt_error == pytest.approx(tilt, abs=math.radians(1.0))
    # Left of the robot is a positive pan error.
    assert ball_xy[1] == 0 or math.copysign(1, det.pan_error) == math.copysign(1, ball_xy[1])


def test_no_ball_on_the_field_is_not_found(finder: BallFinder) -> None:
    img, _ = render(None)
    assert not finder.find(img).found


def test_a_ball_behind_the_camera_is_not_drawn(finder: BallFinder) -> None:
    img, _ = render((-0.5, 0.0))
    assert not finder.find(img).found


def photo(seed: int = 0) -> np.ndarray:
    """A webcam-like indoor scene: a beige wall, a grey floor, clutter, uneven light."""
    rng = np.random.default_rng(seed)
    img = np.zeros((240, 320, 3), np.float32)
    img[:110] = (170, 190, 205)  # wall (BGR)
    img[110:] = (95, 100, 105)  # floor
    cv2.rectangle(img, (20, 60), (70, 130), (60, 120, 40), -1)  # a green box
    cv2.rectangle(img, (250, 40), (300, 100), (200, 150, 40), -1)  # a blue poster
    yy = np.linspace(0.8, 1.15, 240, dtype=np.float32)[:, None, None]
    return img * yy + rng.normal(0, 2, img.shape).astype(np.float32)


def draw_ball(img: np.ndarray, centre: tuple[int, int], radius: int) -> None:
    cv2.circle(img, centre, radius, (30, 35, 190), -1, cv2.LINE_AA)
    # A highlight and a darker lower half, as under a ceiling light.
    cv2.circle(
        img,
        (centre[0] - radius // 3, centre[1] - radius // 3),
        radius // 3,
        (90, 90, 235),
        -1,
        cv2.LINE_AA,
    )
    cv2.ellipse(img, centre, (radius, radius), 0, 20, 160, (20, 20, 120), max(2, radius // 4))


def finish(img: np.ndarray, noise: float, blur: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if blur:
        img = cv2.GaussianBlur(img, (blur, blur), 0)
    img = img + rng.normal(0, noise, img.shape).astype(np.float32)
    return np.clip(img, 0, 255).astype(np.uint8)


def assert_ball_at(finder: BallFinder, img: np.ndarray, centre: tuple[int, int]) -> None:
    """The finder finds the ball in ``img`` within 3 pixels of where it was drawn."""
    det = finder.find(img)
    assert det.found
    assert (det.x, det.y) == pytest.approx(centre, abs=3)


@pytest.mark.parametrize(("noise", "blur"), [(2.0, 0), (12.0, 0), (4.0, 5), (10.0, 7)])
def test_finds_a_ball_in_a_noisy_blurred_photo(finder: BallFinder, noise, blur) -> None:
    img = photo()
    draw_ball(img, (210, 170), 14)
    assert_ball_at(finder, finish(img, noise, blur), (210, 170))


def test_a_red_shirt_too_large_to_be_the_ball_is_ignored(finder: BallFinder) -> None:
    img = photo(2)
    # Someone in a red shirt fills a third of the frame behind the ball.
    cv2.rectangle(img, (0, 0), (150, 175), (40, 30, 200), -1)
    draw_ball(img, (240, 190), 12)
    assert_ball_at(finder, finish(img, 5.0, 3), (240, 190))


def test_a_red_shirt_alone_is_not_a_ball(finder: BallFinder) -> None:
    img = photo(3)
    cv2.rectangle(img, (0, 0), (150, 175), (40, 30, 200), -1)
    assert not finder.find(finish(img, 5.0, 3)).found


def test_a_long_red_stripe_is_not_a_ball(finder: BallFinder) -> None:
    img = photo(4)
    cv2.rectangle(img, (20, 200), (300, 212), (40, 30, 200), -1)
    assert not finder.find(finish(img, 3.0, 0)).found


def test_specks_below_the_minimum_size_are_not_a_ball(finder: BallFinder) -> None:
    img = photo(5)
    draw_ball(img, (160, 150), 2)  # 0.02 % of the image
    assert not finder.find(finish(img, 2.0, 0)).found


def test_other_colours_by_name(ballplay: dict) -> None:
    img = photo(6)
    cv2.circle(img, (100, 160), 15, (200, 80, 20), -1)  # a blue ball
    img = finish(img, 3.0, 3)
    blue = BallFinder(FinderSettings.from_config(ballplay, "blue"))
    red = BallFinder(FinderSettings.from_config(ballplay, "red"))
    assert blue.find(img).found
    assert blue.find(img).x == pytest.approx(100, abs=3)
    assert not red.find(img).found


def test_an_unknown_colour_names_the_known_ones(ballplay: dict) -> None:
    with pytest.raises(ConfigError, match=r"unknown ball colour 'mauve'.*red"):
        color_range(ballplay, "mauve")


def test_hue_wraps_around_zero(ballplay: dict) -> None:
    red = color_range(ballplay, "red")
    hsv = np.zeros((1, 4, 3), np.uint8)
    hsv[0, :, 1:] = 255
    hsv[0, :, 0] = [0, 178, 5, 90]  # 0°, 356°, 10°, 180° in OpenCV's half degrees
    assert red.mask(hsv)[0].tolist() == [255, 255, 255, 0]


def test_a_grey_image_is_refused_with_its_shape(finder: BallFinder) -> None:
    with pytest.raises(ValueError, match=r"BGR image.*\(240, 320\)"):
        finder.find(np.zeros((240, 320), np.uint8))


def test_pixel_to_angle_is_the_frameworks_law(finder: BallFinder) -> None:
    pan, tilt = finder.angles(0.0, 240.0, 320, 240)
    assert math.degrees(pan) == pytest.approx(29.0)
    assert math.degrees(tilt) == pytest.approx(-23.0)
