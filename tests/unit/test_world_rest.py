"""A world standing still skips its step (``SimWorld.step``'s rest): that must never change what
the robot feels or where anything is. Two kinematic worlds live the same seeded random life
(stances held for a while, feet lifted and set down, leans that fall, crouches that get up,
placements, shoves, a rolling ball, steps of any length); one always runs the whole step. After
every step both report the same IMU and hold the same state, to the bit."""

from __future__ import annotations

import dataclasses
import random
from collections.abc import Callable

import numpy as np
import pytest

from robot_daemon.plant.world import SimWorld
from robot_daemon.plant.world_settings import WorldSettings
from tests.unit.test_world_model import feet, stance

Positions = dict[int, float]


def _poses(rng: random.Random) -> Callable[[], Positions]:
    """A pose a robot may hold: a stance, a lean that may tip it, a foot lifted, a crouch."""
    roll = rng.random()
    knee, lean = rng.uniform(0.3, 1.2), rng.choice([0.0, 0.0, 0.05, -0.05, 0.9, -0.9])
    home, dx = (0.0, 0.0, -0.19), rng.uniform(-0.04, 0.04)
    swing = (dx, 0.0, rng.choice([-0.17, -0.195]))  # lifted, or set down lower: it takes over
    if roll < 0.6:
        return lambda: stance(knee, lean)
    if roll < 0.85:
        return lambda: feet(swing, home) if rng.random() < 0.5 else feet(home, swing)
    return lambda: stance(2.6, 0.0)  # a crouch: the first half of a get-up


def _op(rng: random.Random) -> Callable[[SimWorld], None]:
    """One thing that happens to the world from outside, the same for any world it is given."""
    roll = rng.random()
    x, y, yaw = rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-3, 3)
    vx, vy = rng.choice([0.0, 0.0, 0.3, -1.0]), rng.choice([0.0, 0.2])
    shove = (rng.choice([5.0, 40.0, -40.0]), 0.0, 0.0)

    def op(world: SimWorld) -> None:
        if roll < 0.03:
            world.place_robot(x, y, yaw)
        elif roll < 0.07:
            world.place_ball(x * 0.3, y * 0.3, vx, vy)
        elif roll < 0.08:
            world.remove_ball()
        elif roll < 0.10:
            world.push(shove, 0.1)

    return op


def _state(world: SimWorld, imu: tuple[np.ndarray, np.ndarray]) -> tuple[object, ...]:
    ball = world.ball.state
    return (
        world._fingerprint(), world.time, world.falls, world.body.state(),
        dataclasses.replace(world.snapshot(), stamp=0.0),
        None if ball is None else (ball.x, ball.y, ball.vx, ball.vy), world.ball.touches,
        imu[0].tobytes(), imu[1].tobytes(),
    )  # fmt: skip


@pytest.mark.parametrize("seed", range(3))
def test_a_world_skipped_at_rest_feels_and_holds_what_a_stepped_one_does(seed: int) -> None:
    settings = WorldSettings(robot_start=(0.0, 0.0, 0.0), ball_start=(0.3, 0.0))
    skipping, stepping = SimWorld(settings, seed=1), SimWorld(settings, seed=1)
    updates = [0]
    whole = skipping.body.update

    def counted(positions: Positions, dt: float) -> None:
        updates[0] += 1
        whole(positions, dt)

    skipping.body.update = counted  # type: ignore[method-assign]
    rng = random.Random(seed)
    steps = 0
    pose = stance()
    for _ in range(300):
        if rng.random() < 0.3:
            pose = _poses(rng)()
        op = _op(rng)
        op(skipping)
        op(stepping)
        for _ in range(rng.choice([1, 3, 20, 60])):
            dt = rng.choice([0.0, 0.001, 0.004, 0.01, 0.01, 0.03])
            stepping._rest = None  # this one never rests
            a = skipping.step(dt, pose)
            b = stepping.step(dt, pose)
            steps += 1
            assert _state(skipping, a) == _state(stepping, b)
    # Not vacuous: many steps were skipped, and many were not; the robot fell and stood again.
    assert steps / 10 < updates[0] < steps * 0.7, (updates[0], steps)
    assert skipping.falls > 0


def test_a_world_at_rest_still_sees_a_servo_move_and_a_hand_that_places_it() -> None:
    world = SimWorld(WorldSettings(robot_start=(0.0, 0.0, 0.0), ball_start=None), seed=1)
    for _ in range(50):
        world.step(0.01, stance())
    assert world._rest is not None  # standing still: at rest
    world.place_robot(0.5, 0.0, 0.0)
    world.step(0.01, stance())
    assert world.snapshot().robot["x"] == pytest.approx(0.5)
    gyro, _ = world.step(0.01, stance(0.6, 0.3))  # the ankles lean it: the body turns
    assert abs(gyro[1]) > 0.1
