"""The MJCF model is generated from the body description and means what the body means."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from config.body import default_body
from robot_daemon.plant.physics.mjcf_model import CAMERA, ROOT, world_mjcf
from schemas.kinematics import camera_pose, leg_fk


def _model() -> tuple[mujoco.MjModel, mujoco.MjData]:
    m = mujoco.MjModel.from_xml_string(world_mjcf())
    return m, mujoco.MjData(m)


def test_generated_model_loads_with_the_bodys_masses_and_every_servo() -> None:
    body = default_body()
    m, _ = _model()
    robot = [b for b in range(m.nbody) if m.body_rootid[b] == m.body(ROOT).id]
    assert sum(m.body_mass[b] for b in robot) == pytest.approx(body.total_mass())
    assert m.nu == 20
    assert m.opt.timestep == pytest.approx(0.001)
    for j in body.servo_joints():
        assert m.actuator(f"servo_{j.servo_id}").trnid[0] == m.joint(j.name).id


def test_joint_angles_are_servo_angles_sole_and_camera_where_kinematics_puts_them() -> None:
    """Same servo angles → the same sole and camera poses as schemas.kinematics (directions
    and zero included), relative to the torso."""
    body = default_body()
    m, d = _model()
    rng = np.random.default_rng(4)
    angles = {j.servo_id: float(rng.uniform(-0.4, 0.4)) for j in body.servo_joints()}
    for j in body.servo_joints():
        d.qpos[m.joint(j.name).qposadr[0]] = angles[j.servo_id]
    mujoco.mj_forward(m, d)
    torso = m.body(ROOT).id
    t_wb = np.eye(4)
    t_wb[:3, :3] = d.xmat[torso].reshape(3, 3)
    t_wb[:3, 3] = d.xpos[torso]
    inv = np.linalg.inv(t_wb)
    for side, site in (("left", "l_sole"), ("right", "r_sole")):
        p = inv @ np.array([*d.site(site).xpos, 1.0])
        assert p[:3] == pytest.approx(leg_fk(angles, side)[:3, 3], abs=1e-6)
    cam = inv @ np.array([*d.cam(CAMERA).xpos, 1.0])
    expected = camera_pose(angles)
    assert cam[:3] == pytest.approx(expected[:3, 3], abs=1e-6)
    # MuJoCo cameras look along their −z: that is the camera frame's optical axis (x).
    look = inv[:3, :3] @ (-d.cam(CAMERA).xmat.reshape(3, 3)[:, 2])
    assert look == pytest.approx(expected[:3, 0], abs=1e-6)
