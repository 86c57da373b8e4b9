"""The training model (``[physics.fast]``: 4 ms steps, no ball) is the full plant's robot with a
faster solver, and the whole robot still behaves on it as on the full model: the daemon's gait
walks it (tests/physics/test_walk.py's figures), a push topples it and the get-up pages stand it
up again (tests/physics/test_falls.py's), through the same emulator, bus and motion code."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest

from config.loader import load_all
from robot_daemon.plant.physics import DirectPlant, PhysicsSettings
from robot_daemon.plant.physics.mjcf_model import world_mjcf
from tests.physics import test_falls, test_walk


def fast_config() -> dict[str, Any]:
    """The merged config with ``[physics.fast]`` laid over ``[physics]``: the emulator's plant
    becomes the training model."""
    cfg = copy.deepcopy(load_all())
    physics = cfg["physics"]
    cfg["physics"] = {**{k: v for k, v in physics.items() if k != "fast"}, **physics["fast"]}
    return cfg


def test_the_fast_model_is_the_full_robot_with_a_faster_solver() -> None:
    import mujoco

    cfg = load_all()
    full_s, fast_s = PhysicsSettings.from_config(cfg), PhysicsSettings.from_config(cfg, fast=True)
    assert (full_s.timestep, fast_s.timestep) == (0.001, 0.004) and not fast_s.ball
    full = mujoco.MjModel.from_xml_string(world_mjcf(settings=full_s))
    fast = mujoco.MjModel.from_xml_string(world_mjcf(settings=fast_s))
    # The same bodies, geoms, joints and actuators, less the ball's body, geom and free joint.
    assert (full.nbody - 1, full.ngeom - 1, full.njnt - 1) == (fast.nbody, fast.ngeom, fast.njnt)
    assert full.nu == fast.nu == 20
    robot = slice(0, fast.nbody)
    np.testing.assert_array_equal(full.body_mass[robot], fast.body_mass)
    np.testing.assert_array_equal(full.geom_size[: fast.ngeom], fast.geom_size)
    np.testing.assert_array_equal(full.jnt_range[: fast.njnt], fast.jnt_range)
    np.testing.assert_array_equal(full.dof_armature[: fast.nv], fast.dof_armature)
    assert fast.opt.integrator == full.opt.integrator and fast.opt.cone == full.opt.cone
    with pytest.raises(ValueError, match="no ball"):
        DirectPlant(np.full(20, 32)).place_ball(0.5, 0.0)


def test_the_gait_walks_the_fast_model_as_the_full_one() -> None:
    w = test_walk.walk(0.1, 0.0, 0.0, settings=fast_config())
    # tests/physics/test_walk.py's figures for the full model
    assert w.falls == 0
    assert 0.8 <= w.forward <= 1.2
    assert abs(w.turned) < 15.0


@pytest.mark.parametrize("direction", ["forward", "backward"])
def test_a_push_topples_the_fast_model_and_the_get_up_page_stands_it_up(
    direction: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MUJOCO_GL", "disable")  # no camera here
    t = test_falls.one_try(direction, 100, settings=fast_config())
    print(f"{direction}: {t}")
    assert t.seen == direction and t.page == test_falls.PAGE[direction]
    assert t.stood
