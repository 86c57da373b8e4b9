"""The robot's body on the field: support-foot odometry, tilt, IMU and falls.

Each step the legs' forward kinematics (from the servos' *present* positions) give both soles
in the body frame. The lower sole is the support foot: it stays where it is on the field, flat,
and the body is placed relative to it, so the body pose (position, height, yaw *and* tilt)
follows from the leg motion alone. When the other foot becomes the lower one it lands flat where
the kinematics put it, and becomes the support. A walking engine that does not swing its feet
goes nowhere; one that leans too far falls.

Falls: the body tilts past ``tilt_limit``, or the centre of mass stays outside the support region
(the support sole, or both soles' hull when both touch) for ``com_outside_s``. Then the body lies
on its front or back until a get-up motion is seen: a crouch (body low over the feet) followed by
standing with the body upright.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_daemon.plant.world_settings import FallSettings, FeetSettings, ImuSettings
from schemas import units
from schemas.kinematics import (
    SIDES,
    Positions,
    Side,
    leg_fk,
    matrix_rpy,
    rot_y,
    rot_z,
    servo_to_leg_angles,
    transform,
)

# The other foot takes over when it is this much lower than the support foot (m).
_SWITCH_DZ = 0.001
# Both feet count as touching when their heights differ by less than this (m).
_DOUBLE_SUPPORT_DZ = 0.004
# Body frame height (m) a robot is placed at before its legs are known.
_NOMINAL_HEIGHT = 0.29
# A felt body rate below this (rad/s) is none: the CM-730's gyro resolves ~0.01 rad/s.
_FELT_ZERO = 1e-9


def flatten(pose: np.ndarray) -> np.ndarray:
    """The pose laid flat on the ground: same x, y and heading, z = 0, no roll or pitch."""
    yaw = math.atan2(pose[1, 0], pose[0, 0])
    return transform(rot_z(yaw), (pose[0, 3], pose[1, 3], 0.0))


def planar(x: float, y: float, yaw: float, z: float = 0.0) -> np.ndarray:
    return transform(rot_z(yaw), (x, y, z))


@dataclass
class BodyState:
    """The kinematic body's place on the field and whether it has fallen."""

    x: float
    y: float
    yaw: float
    fallen: str  # "none" | "forward" | "backward"


class Body:
    def __init__(
        self, feet: FeetSettings, falls: FallSettings, imu: ImuSettings | None = None
    ) -> None:
        self.feet = feet
        self.falls = falls
        self.imu_settings = imu or ImuSettings()
        self.support: Side = "right"
        self.support_world = np.eye(4)
        self.T_wb = np.eye(4)  # body in the field frame
        self.soles_b: dict[Side, np.ndarray] = {s: np.eye(4) for s in SIDES}
        self.soles_w: dict[Side, np.ndarray] = {s: np.eye(4) for s in SIDES}
        self.sole_velocity: dict[Side, np.ndarray] = {s: np.zeros(3) for s in SIDES}
        # Where the soles and the body's rotation were at the last step (set at placing).
        self._last_soles_w: dict[Side, np.ndarray] = {s: np.eye(4) for s in SIDES}
        self._last_R = np.eye(3)
        self.gyro = np.zeros(3)  # body rate, rad/s, body axes (right-hand rule)
        self._gyro_felt = np.zeros(3)  # what the IMU feels: lagged by the body's compliance
        self.fallen = "none"
        self.com_outside = 0.0
        self._crouched = False
        self._initialised = False
        self._pending_place: tuple[float, float, float] | None = None
        # Each sole's pose with the leg's servo angles it came from: a robot standing still
        # (most of the time) does not compute the same kinematics 100 times a second.
        self._soles_at: dict[Side, tuple[tuple[float, ...], np.ndarray]] = {}

    # -- placing -------------------------------------------------------------------------------
    def place(self, x: float, y: float, yaw: float) -> None:
        """Stand the robot at (x, y) facing ``yaw`` (applied at the next update)."""
        self._pending_place = (x, y, yaw)
        if not self._initialised:  # until the legs are known, stand at a nominal height
            self.T_wb = planar(x, y, yaw, _NOMINAL_HEIGHT)
        self.fallen = "none"
        self.com_outside = 0.0

    def _place_now(self, x: float, y: float, yaw: float) -> None:
        # Where the body would be if the support sole lay flat: then shift that to (x, y, yaw).
        sole = self.soles_b[self.support]
        body_on_sole = flatten(np.linalg.inv(sole))  # body relative to a flat support sole
        # body_world = support_world @ inv(sole)  ⇒ choose support_world so the body lands at x, y.
        self.support_world = planar(x, y, yaw) @ np.linalg.inv(body_on_sole)
        self.support_world = flatten(self.support_world)
        self.T_wb = self.support_world @ np.linalg.inv(sole)
        for s in SIDES:
            self.soles_w[s] = self.T_wb @ self.soles_b[s]

    # -- the step --------------------------------------------------------------------------------
    def _sole(self, positions: Positions, side: Side) -> np.ndarray:
        angles = servo_to_leg_angles(positions, side)
        known = self._soles_at.get(side)
        if known is not None and known[0] == angles:
            return known[1]
        sole = leg_fk(positions, side)
        sole.flags.writeable = False  # shared by later steps: nobody may change it
        self._soles_at[side] = (angles, sole)
        return sole

    def update(self, positions: Positions, dt: float) -> None:
        soles = {s: self._sole(positions, s) for s in SIDES}
        self.soles_b = soles
        if not self._initialised:
            self.support = min(SIDES, key=lambda s: soles[s][2, 3])
            self._initialised = True
            if self._pending_place is None:
                self._pending_place = (0.0, 0.0, 0.0)
        if self._pending_place is not None:
            self._place_now(*self._pending_place)
            self._pending_place = None
            self._last_soles_w = {s: self.soles_w[s].copy() for s in SIDES}
            self._last_R = self.T_wb[:3, :3].copy()
            return
        if self.fallen != "none":
            self._update_fallen(soles)
        else:
            self._update_standing(soles, dt)
        for s in SIDES:
            self.soles_w[s] = self.T_wb @ soles[s]
            if dt > 0:
                self.sole_velocity[s] = (self.soles_w[s][:3, 3] - self._last_soles_w[s][:3, 3]) / dt
            self._last_soles_w[s] = self.soles_w[s].copy()
        r = self.T_wb[:3, :3]
        if dt > 0:
            d = self._last_R.T @ r  # body-frame rotation over the step
            self.gyro = np.array([d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]]) / (
                2 * dt
            )
            lag = self.imu_settings.gyro_lag_s
            self._gyro_felt += (self.gyro - self._gyro_felt) * dt / (lag + dt)
            # The lag decays geometrically and would take ~1 800 steps to reach 0.0 exactly;
            # a rate a billion times below the gyro's resolution is none, and a body whose
            # felt rate is none can be at rest (``SimWorld.step``).
            self._gyro_felt[np.abs(self._gyro_felt) < _FELT_ZERO] = 0.0
        self._last_R = r.copy()

    def _update_standing(self, soles: dict[Side, np.ndarray], dt: float) -> None:
        other: Side = "left" if self.support == "right" else "right"
        r = self.T_wb[:3, :3]
        z = {s: float((r @ soles[s][:3, 3])[2]) for s in SIDES}
        if z[other] < z[self.support] - _SWITCH_DZ:
            self.support_world = flatten(self.T_wb @ soles[other])
            self.support = other
        self.T_wb = self.support_world @ np.linalg.inv(soles[self.support])
        double = abs(z["left"] - z["right"]) < _DOUBLE_SUPPORT_DZ
        self._check_fall(soles, double, dt)

    # -- rest ------------------------------------------------------------------------------------
    def still(self) -> bool:
        """Nothing in the body moves: no body rate (felt or not), no sole velocity. A step of a
        still body that changed nothing changes nothing again, however long the step: each
        term that scales with it is zero (time with the centre of mass outside grows, so such
        a step changed something)."""
        return not (
            self.gyro.any()
            or self._gyro_felt.any()
            or any(v.any() for v in self.sole_velocity.values())
        )

    def fingerprint(self) -> tuple[object, ...]:
        """Everything a step reads or writes, as a value to compare."""
        arrays = [
            self.T_wb, self.support_world, self.gyro, self._gyro_felt,
            *self.soles_b.values(), *self.soles_w.values(), *self.sole_velocity.values(),
            *self._last_soles_w.values(), self._last_R,
        ]  # fmt: skip
        return (
            b"".join(a.tobytes() for a in arrays),
            self.support, self.fallen, self.com_outside, self._crouched, self._initialised,
            self._pending_place,
        )  # fmt: skip

    # -- falls ------------------------------------------------------------------------------------
    def tilt(self) -> float:
        return math.acos(max(-1.0, min(1.0, float(self.T_wb[2, 2]))))

    def com_world(self) -> np.ndarray:
        return (self.T_wb @ np.array([*self.falls.com_offset, 1.0]))[:3]

    def support_polygon(self, double: bool) -> np.ndarray:
        """Corners (n, 2) of the support region on the field."""
        hl, hw = self.feet.length / 2, self.feet.width / 2
        corners = np.array([[hl, hw, 0, 1], [-hl, hw, 0, 1], [-hl, -hw, 0, 1], [hl, -hw, 0, 1.0]])
        sides = SIDES if double else (self.support,)
        pts = np.vstack(
            [(flatten(self.T_wb @ self.soles_b[s]) @ corners.T).T[:, :2] for s in sides]
        )
        return _convex_hull(pts)

    def com_margin(self, double: bool) -> float:
        """Signed distance of the centre of mass inside the support region (negative: outside)."""
        return _inside_distance(self.support_polygon(double), self.com_world()[:2])

    def _check_fall(self, soles: dict[Side, np.ndarray], double: bool, dt: float) -> None:
        f = self.falls
        outside = self.com_margin(double) < -f.com_margin
        self.com_outside = self.com_outside + dt if outside else 0.0
        if self.tilt() > f.tilt_limit or self.com_outside > f.com_outside_s:
            com = self.com_world() - self.support_world[:3, 3]
            heading = self.support_world[:3, 0]
            self._fall("forward" if float(com @ heading) >= 0 else "backward")

    def _fall(self, direction: str) -> None:
        yaw = math.atan2(self.T_wb[1, 0], self.T_wb[0, 0])
        x, y = self.T_wb[0, 3], self.T_wb[1, 3]
        sign = 1.0 if direction == "forward" else -1.0
        # Lying on its front (x axis down) or back, torso a chest's depth above the ground.
        self.T_wb = planar(x, y, yaw, 0.05) @ transform(rot_y(sign * math.pi / 2))
        self.fallen = direction
        self.com_outside = 0.0
        self._crouched = False

    def _update_fallen(self, soles: dict[Side, np.ndarray]) -> None:
        f = self.falls
        height = -max(float(soles[s][2, 3]) for s in SIDES)  # body above the higher sole
        if height < f.crouch_height:
            self._crouched = True
            return
        if not self._crouched or height < f.stand_height:
            return
        sole = soles[min(SIDES, key=lambda s: soles[s][2, 3])]
        roll, pitch, _ = matrix_rpy(sole[:3, :3])
        if math.hypot(roll, pitch) > f.stand_tilt:
            return
        yaw = math.atan2(self.T_wb[1, 0], self.T_wb[0, 0])
        self.fallen = "none"
        self._crouched = False
        self.support = min(SIDES, key=lambda s: soles[s][2, 3])
        self.soles_b = soles
        self._place_now(self.T_wb[0, 3], self.T_wb[1, 3], yaw)

    # -- outputs -----------------------------------------------------------------------------------
    def state(self) -> BodyState:
        yaw = self.heading()
        return BodyState(float(self.T_wb[0, 3]), float(self.T_wb[1, 3]), yaw, self.fallen)

    def heading(self) -> float:
        """Yaw of the body's forward axis projected on the ground (rad)."""
        # Lying on its front the head (body z) points the way it faced; on its back, away.
        fwd = {"none": self.T_wb[:3, 0], "forward": self.T_wb[:3, 2]}.get(
            self.fallen, -self.T_wb[:3, 2]
        )
        return math.atan2(fwd[1], fwd[0])

    def imu(self) -> tuple[np.ndarray, np.ndarray]:
        """(gyro rad/s, specific force m/s²) in robot axes, as the CM-730 feels them."""
        accel = self.T_wb[:3, :3].T @ np.array([0.0, 0.0, units.GRAVITY])
        return self._gyro_felt.copy(), accel


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise hull of 2-D points (monotone chain)."""
    pts = sorted({(float(p[0]), float(p[1])) for p in points})
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, float]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _inside_distance(poly: np.ndarray, p: np.ndarray) -> float:
    """Signed distance from ``p`` to the edges of a CCW convex polygon, positive inside."""
    best = math.inf
    n = len(poly)
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        edge = b - a
        length = float(np.hypot(*edge))
        if length < 1e-12:
            continue
        # Left of a CCW edge is inside.
        d = float(edge[0] * (p[1] - a[1]) - edge[1] * (p[0] - a[0])) / length
        best = min(best, d)
    return best
