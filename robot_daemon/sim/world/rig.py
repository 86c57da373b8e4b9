"""A whole simulated robot on a simulated clock, in one thread: servo dynamics (the emulator's
bus model, advanced by :meth:`Emulator.advance`), the world, the daemon's motion manager with
every module :func:`build_manager` adds, and the ball finder on rendered frames.

No pseudo-terminal and no Zenoh: the rig writes goals into the servos' control tables and reads
their present state directly, so a minute of play runs in a few seconds. The motion and vision
code is the daemon's own; only the transport is skipped. Tests and the ball play benchmark use
it:

    rig = SimRig(seed=3)
    rig.world.place_ball(0.5, 0.2)
    rig.ball_play.start()
    rig.run_until(lambda r: not r.ball_play.playing, timeout=60.0)
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from config.loader import RobotConfig, load_all, robot_from_dict
from robot_daemon.bus.tables import MX28
from robot_daemon.motion.interface import JointFrame, Targets
from robot_daemon.motion.setup import build_manager
from robot_daemon.sim.emulator import Emulator
from robot_daemon.sim.world.settings import WorldSettings
from robot_daemon.sim.world.world import SimWorld
from robot_daemon.vision.ball_finder import BallFinder, FinderSettings
from schemas import units
from schemas.messages import BallDetection

TICK_S = 0.008


class SimRig:
    def __init__(
        self,
        seed: int = 1,
        settings: dict[str, Any] | None = None,
        world: WorldSettings | None = None,
        initial_positions: dict[int, float] | None = None,
        vision_fps: float | None = None,
    ) -> None:
        self.settings = settings if settings is not None else load_all()
        self.robot: RobotConfig = robot_from_dict(self.settings["robot"])
        raw = {
            j: units.rad_to_raw(self._servo_angle(j, a))
            for j, a in (initial_positions or {}).items()
        }
        self.emulator = Emulator(
            realtime=False,
            wire_timing=False,
            seed=seed,
            imu_noise=0.0,
            power_on_delay_s=0.0,
            initial_positions=raw,
        )
        self.world = SimWorld(
            world or WorldSettings.from_config(self.settings.get("world", {})), seed=seed
        )
        self.world.attach(self.emulator)
        self.manager = build_manager(self.robot, self.settings)
        self.finder = BallFinder(FinderSettings.from_config(self.settings.get("ballplay", {})))
        fps = vision_fps or self.world.settings.render.fps
        self.vision_period = 1.0 / fps
        self.time = 0.0
        self.tick = 0
        self.detections: list[BallDetection] = []
        self._next_vision = 0.0
        self._written: dict[int, int] = {}
        self._gains: dict[int, tuple[int, int, int]] = {}
        self._power_on()
        self.world.step(0.0, self.emulator.present_positions())

    # -- conversions (what RobotBus does on the wire) ---------------------------------------------
    def _servo_angle(self, jid: int, joint_rad: float) -> float:
        j = self.robot.joint(jid)
        return j.direction * joint_rad + math.radians(j.offset_deg)

    def _joint_angle(self, jid: int, servo_rad: float) -> float:
        j = self.robot.joint(jid)
        return j.direction * (servo_rad - math.radians(j.offset_deg))

    def _power_on(self) -> None:
        bus = self.emulator.bus
        bus.cm730.write(24, b"\x01")  # DXL_POWER
        self.emulator.advance(0.01)
        for s in bus.servos.values():
            s.write(MX28.TORQUE_ENABLE.reg.address, b"\x01")

    @property
    def ball_play(self) -> Any:
        return self.manager.module("ball")

    # -- the loop --------------------------------------------------------------------------------
    def frame(self) -> JointFrame:
        f = JointFrame(tick=self.tick, time=self.time, dt=TICK_S)
        for jid, servo in self.emulator.bus.servos.items():
            f.position[jid] = self._joint_angle(jid, float(units.raw_to_rad(servo.position)))
            f.velocity[jid] = self.robot.joint(jid).direction * servo.velocity * units.RAD_PER_UNIT
            f.online[jid] = True
            f.torque_enabled[jid] = bool(servo.table["TORQUE_ENABLE"])
        cm = self.emulator.bus.cm730
        f.gyro = np.array(cm.gyro, dtype=float)
        f.accel = np.array(cm.accel, dtype=float)
        f.gyro_raw = np.array([units.rad_s_to_gyro_raw(v) for v in cm.gyro])
        f.accel_raw = np.array([units.ms2_to_accel_raw(v) for v in cm.accel])
        return f

    def write(self, targets: Targets) -> None:
        # The daemon sync-writes every goal each tick; writing only the changes into the
        # tables leaves the same registers and saves most of the simulated bus's time.
        servos = self.emulator.bus.servos
        for jid, rad in targets.goal.items():
            raw = max(0, min(units.POSITION_MAX, units.rad_to_raw(self._servo_angle(jid, rad))))
            if self._written.get(jid) != raw:
                self._written[jid] = raw
                servos[jid].write(MX28.GOAL_POSITION.reg.address, raw.to_bytes(2, "little"))
        for jid, (p, i, d) in targets.gains.items():
            if self._gains.get(jid) != (p, i, d):
                self._gains[jid] = (p, i, d)
                servos[jid].write(MX28.D_GAIN.reg.address, bytes((d, i, p)))

    def step(self) -> None:
        """One motion tick, then the physics up to the next one, then vision if it is due."""
        targets = self.manager.step(self.frame())
        self.write(targets)
        self.emulator.advance(TICK_S)
        self.time += TICK_S
        self.tick += 1
        if self.time + 1e-9 >= self._next_vision:
            self._next_vision += self.vision_period
            self.see()

    def see(self) -> BallDetection:
        ball = self.manager.get("ball")
        phase = getattr(ball, "phase", "")
        det = self.finder.find(self.world.render(), stamp=self.time, phase=phase)
        self.detections.append(det)
        if ball is not None and getattr(ball, "playing", False):
            ball.offer(det)
        return det

    def run(self, seconds: float) -> None:
        end = self.time + seconds
        while self.time < end - 1e-9:
            self.step()

    def run_until(self, done: Callable[[SimRig], bool], timeout: float) -> bool:
        """Step until ``done(rig)`` (checked every tick) or ``timeout`` simulated seconds."""
        end = self.time + timeout
        while self.time < end:
            if done(self):
                return True
            self.step()
        return done(self)
