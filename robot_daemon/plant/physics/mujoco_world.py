"""The MuJoCo plant: the robot, a field and a ball in rigid-body physics, under the emulator.

:class:`MujocoWorld` has the kinematic :class:`~robot_daemon.plant.world.SimWorld`'s
interface (place robot and ball, snapshot, camera view, render, ``attach``), so the control ops,
the World publication, the camera source and the rig work unchanged. Attached to an
:class:`~robot_daemon.emulator.emulator.Emulator`, every physics step of the emulator

1. reads each servo's registers under the emulator's lock: goal (approached at the moving speed
   register's rate, 0 = at once), torque enable and power, P gain
   (→ stiffness, ``[physics.servo] stiffness_per_p``), torque limit and the supply voltage
   (→ the actuator's force range, stall 2.5 N·m at 12 V), back-EMF damping while torque is on;
2. steps MuJoCo in ``timestep`` (1 ms) steps without any lock but the world's (``mj_step``
   releases the GIL: the bus keeps answering);
3. writes back each joint's position, speed and the motor's torque (present position/speed/load,
   overload and heat follow them) and the IMU sensors at the CM-730 (robot axes, SI; the
   emulator's IMU map turns them into the CM-730's registers).

Time: the emulator's clock, whatever it is: lock-step under :meth:`Emulator.advance` (tests,
faster than real time, deterministic) or the emulator's physics thread in real time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from config.body import default_body
from robot_daemon.bus.tables import MX28
from robot_daemon.plant.ball import BallState
from robot_daemon.plant.camera_model import CameraPose
from robot_daemon.plant.physics.mjcf_model import (
    BALL,
    CAMERA,
    MJ_CAMERA_IN_CAMERA,
    ROOT,
    PhysicsSettings,
    world_mjcf,
)
from robot_daemon.plant.physics.mujoco_camera import WorldCamera
from robot_daemon.plant.views import WorldViews
from robot_daemon.plant.world_settings import WorldSettings
from schemas import units
from schemas.body import Body
from schemas.extras import message

if TYPE_CHECKING:
    from robot_daemon.emulator.emulator import Emulator

MISSING = message("physics", "the MuJoCo plant")
# The servo registers the plant reads each physics round (the MX-28's table).
_GOAL = MX28.GOAL_POSITION.value.address
_TORQUE_ENABLE = MX28.TORQUE_ENABLE.value.address
_P_GAIN = MX28.P_GAIN.value.address
_TORQUE_LIMIT = MX28.TORQUE_LIMIT.value.address
_MOVING_SPEED = MX28.MOVING_SPEED.value.address
assert all(r.value.size == 2 for r in (MX28.GOAL_POSITION, MX28.TORQUE_LIMIT, MX28.MOVING_SPEED))
assert all(r.value.size == 1 for r in (MX28.TORQUE_ENABLE, MX28.P_GAIN))
# Where a removed ball waits, out of the field (m).
_BALL_PARKED = (0.0, 50.0)


def import_mujoco() -> Any:
    """The ``mujoco`` module, or a RuntimeError whose one line names the fix."""
    try:
        import mujoco
    except ImportError:
        raise RuntimeError(MISSING) from None
    return mujoco


@dataclass
class _Ball:
    """The ball as the kinematic world's users read it (``state``, ``touches``)."""

    state: BallState | None = None
    touches: int = 0


class MujocoWorld(WorldViews):
    def __init__(
        self,
        settings: WorldSettings | None = None,
        seed: int | None = None,
        physics: PhysicsSettings | None = None,
        body: Body | None = None,
    ) -> None:
        mj = self.mj = import_mujoco()
        super().__init__(settings or WorldSettings(), seed)
        s = self.settings
        self.physics = p = physics or PhysicsSettings()
        self.body_description = body or default_body()
        field = (s.field.length / 2 + 1.0, s.field.width / 2 + 1.0)
        self.xml = world_mjcf(self.body_description, p, s.ball.radius, field)
        self.model = mj.MjModel.from_xml_string(self.xml)
        self.data = mj.MjData(self.model)
        self.falls = 0
        self.fallen = "none"
        self.pushes = 0
        self._push_until: float | None = None
        self.released = False  # False: held in place until a servo first has torque on
        self._debt = 0.0  # time handed to step() not yet simulated (s)
        self._hook: Any = None
        m = self.model
        servos = self.body_description.servo_joints()
        self.servo_ids = [j.servo_id for j in servos if j.servo_id is not None]
        jids = [mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, j.name) for j in servos]
        self._qadr = np.array([m.jnt_qposadr[j] for j in jids])
        self._dadr = np.array([m.jnt_dofadr[j] for j in jids])
        self._act = np.array(
            [mj.mj_name2id(m, mj.mjtObj.mjOBJ_ACTUATOR, f"servo_{i}") for i in self.servo_ids]
        )
        self._root_q = m.jnt_qposadr[mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, "root")]
        self._root_d = m.jnt_dofadr[mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, "root")]
        ball = mj.mj_name2id(m, mj.mjtObj.mjOBJ_JOINT, "ball_root")  # -1: a model without
        self._ball_q = m.jnt_qposadr[ball] if ball >= 0 else -1
        self._ball_d = m.jnt_dofadr[ball] if ball >= 0 else -1
        self._torso = mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, ROOT)
        self._ball_geom = mj.mj_name2id(m, mj.mjtObj.mjOBJ_GEOM, BALL)
        self._camera = mj.mj_name2id(m, mj.mjtObj.mjOBJ_CAMERA, CAMERA)
        self._robot_geoms = np.array(
            [g for g in range(m.ngeom) if m.body_rootid[m.geom_bodyid[g]] == self._torso]
        )
        self._foot_geoms = np.array(
            [mj.mj_name2id(m, mj.mjtObj.mjOBJ_GEOM, n) for n in ("l_foot", "r_foot")]
        )
        gyro = mj.mj_name2id(m, mj.mjtObj.mjOBJ_SENSOR, "gyro")
        accel = mj.mj_name2id(m, mj.mjtObj.mjOBJ_SENSOR, "accel")
        self._gyro_adr = m.sensor_adr[gyro]
        self._accel_adr = m.sensor_adr[accel]
        self._touching_ball = False
        self.ball = _Ball()
        cam = s.render.camera
        self.camera = WorldCamera(self.model, cam.width, cam.height, self._render_opencv, CAMERA)
        self._positions = np.zeros(len(self.servo_ids))  # servo angles (rad) the robot stands in
        self._setpoint = np.zeros(len(self.servo_ids))  # each servo's profile set point (rad)
        self._pose = s.robot_start
        self._place_robot_now(*s.robot_start)
        if s.ball_start is not None and self._ball_q >= 0:
            self.place_ball(*s.ball_start)
        else:
            self.remove_ball()

    # -- the plant -------------------------------------------------------------------------------
    def attach(self, emulator: Emulator) -> None:
        """Drive ``emulator``'s servos and IMU from now on (each physics step of its clock)."""
        with emulator.lock:
            positions = emulator.api.present_positions()
        with self.lock:
            self._positions = np.array([positions[i] for i in self.servo_ids])
            self._place_robot_now(*self._pose)
            self._setpoint = self._positions.copy()
        self._report(emulator, 0.0, np.zeros(len(self.servo_ids), dtype=bool))

        def hook(dt: float, emu: Emulator) -> None:
            self.step_plant(dt, emu)

        emulator.add_physics_hook(hook)
        self._hook = hook

    def detach(self, emulator: Emulator) -> None:
        if self._hook is not None:
            emulator.remove_physics_hook(self._hook)
            self._hook = None
        with emulator.lock:
            for servo in emulator.bus.servos.values():
                servo.plant_torque = None

    def _commands(self, emulator: Emulator) -> tuple[np.ndarray, ...]:
        # Every physics round: the registers' bytes of all servos at once (one array of their
        # tables), decoded as the table's items are and converted in units' order of operations.
        servos = emulator.bus.servos
        with emulator.lock:
            volts = max(emulator.env.voltage, 0.0)
            chain = [servos[i] for i in self.servo_ids]
            tables = np.frombuffer(b"".join([s.table.data for s in chain]), dtype=np.uint8)
            powered = np.array([s.powered for s in chain])
        t = tables.reshape(len(chain), -1).astype(np.int64)
        goal = units.raw_to_rad(t[:, _GOAL] | (t[:, _GOAL + 1] << 8))
        on = (powered & (t[:, _TORQUE_ENABLE] != 0)).astype(float)
        kp = t[:, _P_GAIN] * self.physics.stiffness_per_p
        limit = (t[:, _TORQUE_LIMIT] | (t[:, _TORQUE_LIMIT + 1] << 8)) / 1023.0
        # A moving speed of 0 is no profile: the motor's own top speed.
        moving = t[:, _MOVING_SPEED] | (t[:, _MOVING_SPEED + 1] << 8)
        rad_s = moving * units.RPM_PER_SPEED_UNIT * 2 * math.pi / 60.0
        speed = np.where(moving != 0, rad_s, np.inf)
        stall = self.physics.stall_torque * volts / 12.0
        return goal, speed, kp * on, self.physics.emf_damping * on, limit * stall * on

    def step_plant(self, dt: float, emulator: Emulator) -> None:
        """Simulate ``dt`` s of the emulator's clock with its servos' present commands."""
        goal, speed, kp, kd, force = self._commands(emulator)
        d, ts = self.data, self.model.opt.timestep
        if not self.released:
            # Held where it was placed (on its stand, as a robot being switched on) until a
            # servo first has torque: a limp robot would otherwise crumple before the daemon
            # powers the bus and holds the pose.
            if not (kp > 0).any():
                with self.lock:
                    self.time += dt
                return
            self.released = True
        with self.lock:
            n = self._due(dt)
            if n <= 0:
                return
            self._set_servos(kp, kd, force)
            self._move_setpoint(goal, speed, kp, n * ts)
            self._run(n)
            self._after_step()
            demand = kp * (self._setpoint - d.qpos[self._qadr])
            saturated = (np.abs(demand) > force + 1e-9) & (force > 0)
        self._report(emulator, n * ts, saturated)

    def _due(self, dt: float) -> int:
        """How many physics steps ``dt`` more of the clock makes due (the rest is carried)."""
        ts = self.model.opt.timestep
        self._debt += dt
        n = int(self._debt / ts + 1e-6)
        if n > 0:
            self._debt -= n * ts
        return n

    def _set_servos(self, kp: np.ndarray, kd: np.ndarray, force: np.ndarray) -> None:
        """The motors' stiffness (N·m/rad), back-EMF damping (N·m·s/rad) and torque limit."""
        m, a = self.model, self._act
        m.actuator_gainprm[a, 0] = kp
        m.actuator_biasprm[a, 1] = -kp
        # Back-EMF outside the torque clip, as in the motor (torque = stall · (duty − ω/ω₀)):
        # it caps the speed at the no-load speed; MuJoCo integrates joint damping implicitly.
        m.dof_damping[self._dadr] = self.physics.damping + kd
        m.actuator_forcerange[a, 0] = -force
        m.actuator_forcerange[a, 1] = force

    def _move_setpoint(
        self, goal: np.ndarray, speed: np.ndarray, kp: np.ndarray, seconds: float
    ) -> None:
        # The firmware moves its set point toward the goal at the moving speed (register
        # 32); a limp servo's set point follows the horn, so torque on never jumps.
        q = self.data.qpos[self._qadr]
        move = np.clip(goal - self._setpoint, -speed * seconds, speed * seconds)
        self._setpoint = np.where(kp > 0, self._setpoint + move, q)
        self.data.ctrl[self._act] = self._setpoint

    def _run(self, n: int) -> None:
        """``n`` physics steps; a push lasts until its end time, which may fall among them."""
        m, d, mj = self.model, self.data, self.mj
        ts = m.opt.timestep
        k = n
        if self._push_until is not None:
            k = min(n, max(0, math.ceil((self._push_until - self.time) / ts - 1e-6)))
        if k:
            mj.mj_step(m, d, nstep=k)
        if k < n:
            d.xfrc_applied[self._torso, :] = 0.0
            self._push_until = None
            mj.mj_step(m, d, nstep=n - k)
        self.time += n * ts

    def _report(self, emulator: Emulator, dt: float, saturated: np.ndarray) -> None:
        d = self.data
        with self.lock:
            q = d.qpos[self._qadr].copy()
            qd = d.qvel[self._dadr].copy()
            tau = d.actuator_force[self._act].copy()
            gyro = d.sensordata[self._gyro_adr : self._gyro_adr + 3].tolist()
            accel = d.sensordata[self._accel_adr : self._accel_adr + 3].tolist()
        raw = (q / units.RAD_PER_UNIT + units.POSITION_CENTER).tolist()
        raw_s = (qd / units.RAD_PER_UNIT).tolist()
        rows = zip(self.servo_ids, raw, raw_s, tau.tolist(), saturated.tolist(), strict=True)
        with emulator.lock:
            servos = emulator.bus.servos
            for i, position, speed, torque, held in rows:
                servos[i].plant_update(position, speed, torque, held, dt)
            emulator.bus.cm730.gyro = tuple(gyro)
            emulator.bus.cm730.accel = tuple(accel)

    def _after_step(self) -> None:
        """Falls, ball touches and the ball's state, from the new state: ``ball.state`` is
        what every reader sees (ball play, benchmarks), so it follows each round of steps."""
        up = self.data.xmat[self._torso].reshape(3, 3)
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, float(up[2, 2])))))
        was = self.fallen
        if tilt > self.physics.fall_tilt_deg:
            # Lying on its front the body's x axis points down.
            self.fallen = "forward" if up[2, 0] < 0 else "backward"
        elif tilt < self.physics.fall_tilt_deg / 2:
            self.fallen = "none"
        if self.fallen != "none" and was == "none":
            self.falls += 1
        touching = False
        if self._ball_geom >= 0 and self.data.ncon:
            # The contacts' geom pairs as one array: a Python loop over MuJoCo's contact
            # structs cost half as much as the physics steps themselves (~1/10 of a test's CPU).
            pairs = self.data.contact.geom
            with_ball = pairs[(pairs == self._ball_geom).any(axis=1)]
            if with_ball.size:  # (np.isin costs more than the rest of this check)
                left, right = self._foot_geoms
                touching = bool(((with_ball == left) | (with_ball == right)).any())
        if touching and not self._touching_ball:
            self.ball.touches += 1
        self._touching_ball = touching
        if self.ball.state is not None:
            self.ball.state = self._ball_state()

    # -- placing ---------------------------------------------------------------------------------
    def _place_robot_now(self, x: float, y: float, yaw: float) -> None:
        """The robot at rest in its present joint angles, upright, the lower sole on the ground."""
        m, d, mj = self.model, self.data, self.mj
        d.qpos[self._qadr] = self._positions
        d.qpos[self._root_q : self._root_q + 3] = (x, y, 0.5)
        d.qpos[self._root_q + 3 : self._root_q + 7] = (
            math.cos(yaw / 2),
            0.0,
            0.0,
            math.sin(yaw / 2),
        )
        d.qvel[self._root_d : self._root_d + 6] = 0.0
        d.qvel[self._dadr] = 0.0
        mj.mj_kinematics(m, d)
        lowest = min(self._geom_bottom(g) for g in self._robot_geoms)
        d.qpos[self._root_q + 2] = 0.5 - lowest
        mj.mj_forward(m, d)
        self.fallen = "none"

    def _geom_bottom(self, g: int) -> float:
        """Lowest z of a box geom (world frame) as placed now."""
        half = self.model.geom_size[g]
        r = self.data.geom_xmat[g].reshape(3, 3)
        return float(self.data.geom_xpos[g][2] - np.abs(r[2]) @ half)

    def place_robot(self, x: float, y: float, yaw: float) -> None:
        """Stand the robot at (x, y) facing ``yaw`` (rad), soles on the ground; clears a fall."""
        with self.lock:
            self._pose = (x, y, yaw)
            self._positions = self.data.qpos[self._qadr].copy()
            self._place_robot_now(x, y, yaw)

    def place_ball(self, x: float, y: float, vx: float = 0.0, vy: float = 0.0) -> None:
        if self._ball_q < 0:
            raise ValueError("this model has no ball ([physics] ball = false)")
        r = self.settings.ball.radius
        with self.lock:
            q, v = self._ball_q, self._ball_d
            self.data.qpos[q : q + 7] = (x, y, r, 1.0, 0.0, 0.0, 0.0)
            # Rolling without slipping: spin about the axis across the motion.
            self.data.qvel[v : v + 6] = (vx, vy, 0.0, -vy / r, vx / r, 0.0)
            self.mj.mj_forward(self.model, self.data)
            self.ball.state = self._ball_state()

    def remove_ball(self) -> None:
        if self._ball_q < 0:
            self.ball.state = None
            return
        with self.lock:
            q, v = self._ball_q, self._ball_d
            self.data.qpos[q : q + 7] = (*_BALL_PARKED, self.settings.ball.radius, 1, 0, 0, 0)
            self.data.qvel[v : v + 6] = 0.0
            self.mj.mj_forward(self.model, self.data)
            self.ball.state = None

    def push(self, force: tuple[float, float, float], duration: float) -> None:
        """Apply ``force`` (N, field frame) at the torso's centre of mass for ``duration`` s of
        simulated time (an impulse of force × duration)."""
        with self.lock:
            self.data.xfrc_applied[self._torso, :3] = force
            self._push_until = self.time + duration
            self.pushes += 1

    def _ball_state(self) -> BallState | None:
        if self._ball_q < 0:
            return None
        if self.ball.state is None and self.data.qpos[self._ball_q + 1] == _BALL_PARKED[1]:
            return None
        q, v = self._ball_q, self._ball_d
        return BallState(
            float(self.data.qpos[q]),
            float(self.data.qpos[q + 1]),
            float(self.data.qvel[v]),
            float(self.data.qvel[v + 1]),
        )

    # -- observing -------------------------------------------------------------------------------
    def robot_pose(self) -> tuple[float, float, float]:
        """(x, y, heading) of the torso on the field: heading of its forward axis (rad)."""
        with self.lock:
            pos = self.data.xpos[self._torso]
            r = self.data.xmat[self._torso].reshape(3, 3)
            # Lying on its front the head (body z) points the way it faced; on its back, away.
            fwd = {"none": r[:, 0], "forward": r[:, 2]}.get(self.fallen, -r[:, 2])
            return float(pos[0]), float(pos[1]), math.atan2(fwd[1], fwd[0])

    def _robot(self) -> tuple[float, float, float, str]:
        return (*self.robot_pose(), self.fallen)

    def _ball_now(self) -> BallState | None:
        if self.ball.state is not None:
            self.ball.state = self._ball_state()
        return self.ball.state

    def _camera_pose(self) -> CameraPose:
        pos = self.data.cam_xpos[self._camera].copy()
        # Back from MuJoCo's camera axes to the renderer's (x optical axis, z up).
        r = self.data.cam_xmat[self._camera].reshape(3, 3) @ MJ_CAMERA_IN_CAMERA.T
        return CameraPose(pos, r)

    def render(self) -> np.ndarray:
        """The camera image (BGR, uint8): MuJoCo's offscreen view (EGL/OSMesa), or the OpenCV
        renderer at MuJoCo's camera pose where no GL backend works (:mod:`.camera`)."""
        return self.camera.render(self.lock, self.data)

    def _render_opencv(self) -> np.ndarray:
        return WorldViews.render(self)
