"""The body description, its URDF and the project's forward kinematics agree."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from config.body import default_body
from config.loader import load_robot
from schemas import kinematics as kin
from schemas.urdf import to_urdf
from tests.fixtures.emulator import darwin_command


@pytest.fixture(scope="module")
def yourdfpy():
    # Imported by the tests that load a URDF, not at collection: with trimesh it is ~1 s of CPU
    # in every pytest-xdist worker, and one worker runs these tests.
    return pytest.importorskip("yourdfpy")


@pytest.fixture(scope="module")
def body():
    return default_body()


@pytest.fixture(scope="module")
def urdf(body, yourdfpy):
    return yourdfpy.URDF.load(io.StringIO(to_urdf(body)), build_scene_graph=True, load_meshes=False)


def _random_positions(rng: np.random.Generator, robot) -> np.ndarray:
    q = np.zeros(21)
    for j in robot.joints:
        q[j.id] = rng.uniform(j.min_rad, j.max_rad)
    return q


def test_urdf_link_poses_equal_the_project_fk(body, urdf):
    robot = load_robot()
    rng = np.random.default_rng(14)
    names = {j.servo_id: j.name for j in body.servo_joints()}
    worst = 0.0
    for _ in range(1000):
        q = _random_positions(rng, robot)
        urdf.update_cfg({names[i]: q[i] for i in range(1, 21)})
        ours = body.link_poses(q)
        for link, pose in ours.items():
            theirs = urdf.get_transform(link, "base_link")
            worst = max(worst, float(np.abs(theirs - pose).max()))
        # …and the body description equals schemas.kinematics (the daemon's FK).
        for side in kin.SIDES:
            p = side[0]
            np.testing.assert_allclose(ours[f"{p}_sole"], kin.leg_fk(q, side), atol=1e-9)
            shoulder, elbow, hand = kin.arm_chain(q, side)
            np.testing.assert_allclose(ours[f"{p}_shoulder"][:3, 3], shoulder, atol=1e-9)
            np.testing.assert_allclose(ours[f"{p}_forearm"][:3, 3], elbow, atol=1e-9)
            np.testing.assert_allclose(ours[f"{p}_hand"][:3, 3], hand, atol=1e-9)
        np.testing.assert_allclose(ours["camera"], kin.camera_pose(q), atol=1e-9)
        np.testing.assert_allclose(ours["head"], kin.head_pose(q), atol=1e-9)
    assert worst < 1e-6


def test_joint_names_limits_and_directions_come_from_the_config(body, urdf):
    robot = load_robot()
    assert body.joint_names() == [j.urdf for j in robot.joints]
    assert sorted(urdf.actuated_joint_names) == sorted(j.urdf for j in robot.joints)
    for j in robot.joints:
        uj = urdf.joint_map[j.urdf]
        assert uj.limit.lower == pytest.approx(j.min_rad)
        assert uj.limit.upper == pytest.approx(j.max_rad)
        assert uj.limit.velocity == pytest.approx(robot.max_speed)


def test_positive_servo_angles_move_as_the_framework_says(body):
    """Sign checks against the ROBOTIS framework, not against our own formulas."""
    q = np.zeros(21)
    up = body.link_poses(q)
    # Right knee servo positive = knee bends (Walking.cpp dir +1): the ankle moves backwards.
    q[13] = 0.5
    assert body.link_poses(q)["r_ankle"][0, 3] < up["r_ankle"][0, 3] - 0.01
    # Left knee is mirrored: a negative servo angle bends it.
    q[:] = 0
    q[14] = -0.5
    assert body.link_poses(q)["l_ankle"][0, 3] < up["l_ankle"][0, 3] - 0.01
    # Head pan positive looks left; tilt positive looks up.
    q[:] = 0
    q[19] = 0.5
    assert body.link_poses(q)["camera"][1, 3] > 0.005
    q[:] = 0
    q[20] = math.radians(40)
    cam = body.link_poses(q)["camera"]
    np.testing.assert_allclose(cam[:3, 0], [1, 0, 0], atol=1e-9)  # level at tilt = eye offset


def test_masses_inertias_and_frames(body, urdf):
    total = body.total_mass()
    assert 3.0 < total < 3.2  # the sum of HumaRobotics' link masses, 3.11 kg
    for link in body.links:
        if link.mass > 0:
            ixx, iyy, izz = link.inertia
            assert ixx + iyy >= izz and iyy + izz >= ixx and ixx + izz >= iyy
            assert max(ixx, iyy, izz) < 1e-2  # kg·m², not HumaRobotics' ×1000 values
    for frame in ("camera", "camera_optical", "imu", "r_sole", "l_sole"):
        assert frame in urdf.link_map
    # The optical frame looks along the camera's x axis with its z.
    q = np.zeros(21)
    poses = body.link_poses(q)
    np.testing.assert_allclose(poses["camera_optical"][:3, 2], poses["camera"][:3, 0], atol=1e-9)
    # The foot box's bottom face is the sole.
    foot = next(link for link in body.links if link.name == "r_foot")
    assert foot.box.centre[2] - foot.box.size[2] / 2 == pytest.approx(-kin.ANKLE_LENGTH)


def test_darwin_urdf_writes_a_loadable_file(tmp_path, yourdfpy):
    import subprocess

    out = tmp_path / "darwin.urdf"
    done = subprocess.run(
        darwin_command("urdf", "-o", str(out)),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"urdf: {out}"
    model = yourdfpy.URDF.load(str(out), load_meshes=False)
    assert len(model.actuated_joint_names) == 20
    bad = subprocess.run(
        darwin_command("urdf", "-o", str(tmp_path / "no" / "x.urdf")),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bad.returncode == 1
    assert (
        bad.stderr.strip().startswith("darwin urdf: cannot write") and "Traceback" not in bad.stderr
    )
