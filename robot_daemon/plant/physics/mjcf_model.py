"""The MuJoCo model (MJCF text), generated from the one body description (:mod:`schemas.body`).

Every link with mass becomes a body with its box as collision geometry and its box inertia
(masses and their sources: :mod:`schemas.body`); every servo joint a hinge with the body's axis,
so joint angle = servo angle (raw 2048 = 0) with the servo's direction, and one actuator named
after the servo id (``servo_<id>``) whose gains the plant sets from the registers. Massless
fixed frames become sites: ``imu`` (the CM-730's IMU sensors ``gyro``/``accel`` sit there),
``l_sole``/``r_sole``, and the camera ``head_camera`` at the pose of
:func:`schemas.kinematics.camera_pose`. The root body ``torso`` hangs on a free joint; the world
adds a field plane ``floor`` and a ``ball``.

Robot geoms do not collide with each other (as the primitive models in Webots), only with the
floor and the ball: ``contype`` 2 / ``conaffinity`` 1 for the robot, 1 / 1 for the rest.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any

import numpy as np

from config.body import default_body
from schemas.body import Body, Link

ROOT = "torso"
CAMERA = "head_camera"
BALL = "ball"
FLOOR = "floor"
IMU_SITE = "imu"


# Each sub-table of [physics]: its keys → the PhysicsSettings fields they set.
_TABLES: dict[str, dict[str, str]] = {
    "servo": {
        k: k
        for k in (
            "stall_torque",
            "no_load_rpm",
            "stiffness_per_p",
            "armature",
            "frictionloss",
            "damping",
        )
    },
    "contact": {
        k: k for k in ("foot_friction", "foot_condim", "ball_friction", "ball_mass", "solref")
    },
    "falls": {"tilt_deg": "fall_tilt_deg"},
}
# What [physics.fast] may change: the solver and the world, never the robot or its servos.
_FAST = ("timestep", "integrator", "cone", "ball", "iterations")


# The solver options a model may choose (MuJoCo's names).
INTEGRATORS = ("Euler", "implicitfast", "implicit", "RK4")
CONES = ("elliptic", "pyramidal")


@dataclass(frozen=True)
class PhysicsSettings:
    """The ``[physics]`` section (config/physics.toml), with sources there. ``fast=True`` in
    :meth:`from_config` lays ``[physics.fast]`` over it: the training model (clients/learn)."""

    timestep: float = 0.001
    integrator: str = "implicitfast"
    cone: str = "elliptic"
    ball: bool = True  # the field's ball (a free body: its contacts cost even when parked)
    iterations: int = 100  # the constraint solver's (MuJoCo's default)
    stall_torque: float = 2.5
    no_load_rpm: float = 55.0
    stiffness_per_p: float = 12.6 / 32
    armature: float = 0.02
    frictionloss: float = 0.025
    damping: float = 0.05
    foot_friction: tuple[float, float, float] = (1.0, 0.02, 0.0001)
    foot_condim: int = 3
    ball_friction: tuple[float, float, float] = (0.8, 0.005, 0.002)
    ball_mass: float = 0.045
    solref: tuple[float, float] = (0.02, 1.0)
    fall_tilt_deg: float = 60.0

    @property
    def emf_damping(self) -> float:
        """Back-EMF damping while torque is on (N·m·s/rad): stall torque / no-load speed."""
        return self.stall_torque / (self.no_load_rpm * 2 * math.pi / 60.0)

    @classmethod
    def from_config(cls, data: dict[str, Any], fast: bool = False) -> PhysicsSettings:
        from config.loader import refuse_unknown, section_to
        from schemas.errors import ConfigError

        # config/physics.toml groups the fields in sub-tables; the settings are one flat table.
        p = dict(data.get("physics", {}))
        refuse_unknown(p, (*_FAST, *_TABLES, "fast"), "physics")
        flat = {k: v for k, v in p.items() if k not in _TABLES and k != "fast"}
        for table, keys in _TABLES.items():
            sub = p.get(table, {})
            if not isinstance(sub, dict):
                raise ConfigError(f"[physics] {table} should be a table [physics.{table}]")
            refuse_unknown(sub, keys, f"physics.{table}")
            flat.update({keys[k]: v for k, v in sub.items()})
        overlay = p.get("fast", {})
        if not isinstance(overlay, dict):
            raise ConfigError("[physics] fast should be a table [physics.fast]")
        refuse_unknown(overlay, _FAST, "physics.fast")
        if fast:
            flat.update(overlay)
        s = section_to(cls, flat, "physics")
        if s.integrator not in INTEGRATORS:
            raise ConfigError(f"[physics] integrator={s.integrator!r} is not one of {INTEGRATORS}")
        if s.cone not in CONES:
            raise ConfigError(f"[physics] cone={s.cone!r} is not one of {CONES}")
        if not 0 < s.timestep <= 0.005:
            raise ConfigError(f"[physics] timestep={s.timestep} s must be in (0, 0.005]")
        if s.solref[0] < 2 * s.timestep:
            raise ConfigError(
                f"[physics.contact] solref time constant {s.solref[0]} s must be ≥ 2 × timestep"
            )
        return s


def _fmt(values: Any) -> str:
    return " ".join(f"{float(v):.9g}" for v in np.ravel(values))


def _quat(r: np.ndarray) -> np.ndarray:
    """Rotation matrix → MuJoCo quaternion (w, x, y, z)."""
    w = math.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1.0 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    q = np.array([w, x, y, z])
    return q / np.linalg.norm(q)


# The MJCF camera looks along its −z with y up; the body's camera frame has x along the optical
# axis and z up: camera = body camera frame · R, R's columns being the MJCF axes in that frame.
MJ_CAMERA_IN_CAMERA = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
_SITES = {"imu": IMU_SITE, "l_sole": "l_sole", "r_sole": "r_sole", "camera": CAMERA}


def robot_mjcf(body: Body, s: PhysicsSettings, parent: ET.Element) -> None:
    """The robot's bodies, joints, sites and actuators under ``parent`` (the worldbody); the
    actuators go to a sibling ``actuator`` element the caller adds (see :func:`world_mjcf`)."""
    links = {link.name: link for link in body.links}
    elements: dict[str, ET.Element] = {}
    # A massless fixed frame lives in its nearest real ancestor at this pose.
    carried: dict[str, tuple[str, np.ndarray]] = {}
    root = ET.SubElement(parent, "body", name=ROOT, pos="0 0 0.3")
    ET.SubElement(root, "freejoint", name="root")
    elements[body.root] = root
    _link_contents(root, links[body.root], s)
    for j in body.joints:
        if j.parent in carried:
            owner, pose = carried[j.parent]
        else:
            owner, pose = j.parent, np.eye(4)
        pose = pose @ j.origin()
        child = links[j.child]
        if j.fixed and child.mass <= 0:
            carried[j.child] = (owner, pose)
            if j.child in _SITES:
                r = pose[:3, :3]
                tag = "camera" if j.child == "camera" else "site"
                if tag == "camera":
                    r = r @ MJ_CAMERA_IN_CAMERA
                attrs = {"name": _SITES[j.child], "pos": _fmt(pose[:3, 3]), "quat": _fmt(_quat(r))}
                if tag == "camera":
                    attrs["fovy"] = "46"
                el = ET.SubElement(elements[owner], tag, attrs)
                if tag == "site":
                    el.set("size", "0.005")
            continue
        el = ET.SubElement(
            elements[owner],
            "body",
            name=j.child,
            pos=_fmt(pose[:3, 3]),
            quat=_fmt(_quat(pose[:3, :3])),
        )
        elements[j.child] = el
        if not j.fixed:
            ET.SubElement(
                el,
                "joint",
                name=j.name,
                type="hinge",
                axis=_fmt(j.axis),
                range=f"{j.lower:.9g} {j.upper:.9g}",
                limited="true",
                armature=f"{s.armature:.9g}",
                frictionloss=f"{s.frictionloss:.9g}",
                damping=f"{s.damping:.9g}",
            )
        _link_contents(el, child, s, foot=j.child.endswith("_foot"))


def _link_contents(el: ET.Element, link: Link, s: PhysicsSettings, foot: bool = False) -> None:
    if link.box is None or link.mass <= 0:
        return
    ET.SubElement(
        el,
        "inertial",
        pos=_fmt(link.box.centre),
        mass=f"{link.mass:.9g}",
        diaginertia=_fmt(link.inertia),
    )
    attrs = {
        "name": link.name if link.name != "base_link" else ROOT,
        "type": "box",
        "size": _fmt(np.array(link.box.size) / 2),
        "pos": _fmt(link.box.centre),
        "contype": "2",
        "conaffinity": "1",
        "rgba": "0.25 0.25 0.28 1",
    }
    if foot:
        attrs["friction"] = _fmt(s.foot_friction)
        attrs["condim"] = str(s.foot_condim)
    ET.SubElement(el, "geom", attrs)


def world_mjcf(
    body: Body | None = None,
    settings: PhysicsSettings | None = None,
    ball_radius: float = 0.035,
    field_size: tuple[float, float] = (5.0, 3.5),
) -> str:
    """The whole world: floor, robot on a free joint, ball, IMU sensors, servo actuators."""
    body = body or default_body()
    s = settings or PhysicsSettings()
    m = ET.Element("mujoco", model=body.name)
    m.append(
        ET.Comment(
            " Generated by darwin-zenoh from schemas/body.py"
            " (robot_daemon/plant/physics/mjcf_model.py); do not edit."
            " Sources: schemas/body.py and config/physics.toml. "
        )
    )
    ET.SubElement(m, "compiler", angle="radian", autolimits="true")
    option = ET.SubElement(
        m, "option", timestep=f"{s.timestep:.9g}", integrator=s.integrator, cone=s.cone
    )
    if s.iterations != PhysicsSettings.iterations:
        option.set("iterations", str(s.iterations))
    default = ET.SubElement(m, "default")
    ET.SubElement(default, "geom", solref=_fmt(s.solref))
    visual = ET.SubElement(m, "visual")
    ET.SubElement(visual, "global", offwidth="640", offheight="480")
    asset = ET.SubElement(m, "asset")
    ET.SubElement(
        asset,
        "texture",
        name="grass",
        type="2d",
        builtin="checker",
        rgb1="0.13 0.45 0.18",
        rgb2="0.12 0.42 0.17",
        width="256",
        height="256",
    )
    ET.SubElement(asset, "material", name="grass", texture="grass", texrepeat="20 20")
    world = ET.SubElement(m, "worldbody")
    ET.SubElement(world, "light", pos="0 0 4", dir="0 0 -1", directional="true")
    ET.SubElement(
        world,
        "geom",
        name=FLOOR,
        type="plane",
        size=f"{field_size[0]:.9g} {field_size[1]:.9g} 0.05",
        material="grass",
        friction="1 0.02 0.0001",
        contype="1",
        conaffinity="1",
        condim="3",  # a pair uses the larger condim: the feet and the ball say theirs
    )
    robot_mjcf(body, s, world)
    if s.ball:
        _ball_mjcf(world, s, ball_radius)
    actuators = ET.SubElement(m, "actuator")
    for j in body.servo_joints():
        # Gains and force range are set by the plant from the registers at every step.
        ET.SubElement(
            actuators,
            "general",
            name=f"servo_{j.servo_id}",
            joint=j.name,
            gaintype="fixed",
            biastype="affine",
            gainprm="0",
            biasprm="0 0 0",
            forcerange=f"{-s.stall_torque:.9g} {s.stall_torque:.9g}",
            ctrlrange="-3.1416 3.1416",
        )
    sensors = ET.SubElement(m, "sensor")
    ET.SubElement(sensors, "gyro", name="gyro", site=IMU_SITE)
    ET.SubElement(sensors, "accelerometer", name="accel", site=IMU_SITE)
    ET.indent(m)
    return ET.tostring(m, encoding="unicode") + "\n"


def _ball_mjcf(world: ET.Element, s: PhysicsSettings, ball_radius: float) -> None:
    ball = ET.SubElement(world, "body", name=BALL, pos=f"0 0 {ball_radius:.9g}")
    ET.SubElement(ball, "freejoint", name="ball_root")
    ET.SubElement(
        ball,
        "geom",
        name=BALL,
        type="sphere",
        size=f"{ball_radius:.9g}",
        mass=f"{s.ball_mass:.9g}",
        rgba="0.82 0.11 0.11 1",
        friction=_fmt(s.ball_friction),
        condim="6",
        contype="1",
        conaffinity="1",
    )
