"""A whole simulated robot on a simulated clock, in one thread: servo dynamics (the emulator's
bus model, advanced by :meth:`Emulator.advance`), the world, the daemon's motion manager with
every module :func:`build_manager` adds, and the ball finder on rendered frames.

No pseudo-terminal and no Zenoh: the daemon's own bus code (:class:`RobotBus`: calibration,
frames with the IMU axis map and gyro scale, clamped goal writes, power-on) talks to the
emulator through the in-process link (:class:`EmulatorLink`), whose clock is simulated, so a
minute of play runs in a few seconds. The motion and vision code is the daemon's own too. Tests
and the ball play benchmark use it:

    rig = SimRig(seed=3)
    rig.world.place_ball(0.5, 0.2)
    rig.ball_play.start()
    rig.run_until(lambda r: not r.ball_play.playing, timeout=60.0)
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

from config.loader import RobotConfig, load_all, robot_from_dict
from robot_daemon.bus.calibration import joint_raw
from robot_daemon.bus.robot_bus import RobotBus
from robot_daemon.frames import JointFrame
from robot_daemon.motion.setup import build_manager
from robot_daemon.sim.emulator import Emulator
from robot_daemon.sim.link import EmulatorLink
from robot_daemon.sim.settings import EmulatorSettings
from robot_daemon.sim.world.settings import WorldSettings
from robot_daemon.sim.world.world import SimWorld, make_world
from robot_daemon.vision.ball_finder import BallFinder, FinderSettings
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
        physics: str | None = None,
    ) -> None:
        settings = copy.deepcopy(settings if settings is not None else load_all())
        # The simulated servos answer as soon as they are powered: nothing to wait for.
        settings.setdefault("bus", {})["power_on_delay_ms"] = 0.0
        self.settings = settings
        # The motion tick, as the daemon's [daemon] tick_ms sets it.
        self.tick_s = float(settings.get("daemon", {}).get("tick_ms", TICK_S * 1000)) / 1000
        self.robot: RobotConfig = robot_from_dict(self.settings["robot"])
        raw = {j: joint_raw(self.robot.joint(j), a) for j, a in (initial_positions or {}).items()}
        self.emulator = Emulator(
            EmulatorSettings.from_settings(
                self.settings,
                realtime=False,
                wire_timing=False,
                seed=seed,
                imu_noise=0.0,
                power_on_delay_s=0.0,
                initial_positions=raw,
            ),
        )
        self.world = make_world(
            physics or self.emulator.settings.physics,
            world or WorldSettings.from_config(self.settings.get("world", {})),
            self.settings,
            seed=seed,
        )
        self.world.attach(self.emulator)
        self.manager = build_manager(self.robot, self.settings)
        self.finder = BallFinder(FinderSettings.from_config(self.settings.get("ballplay", {})))
        fps = vision_fps or self.world.settings.render.fps
        self.vision_period = 1.0 / fps
        self.time = 0.0
        self.tick = 0
        self.detections: list[BallDetection] = []
        self.events: list[tuple[str, str, dict[str, Any]]] = []
        self._next_vision = 0.0
        self.link = EmulatorLink(self.emulator)
        self.bus = RobotBus(
            self.link.port_name, self.robot, self.settings, self._emit, transport=lambda: self.link
        )
        # What the daemon does when it connects: power, scan, hold the present pose, torque on.
        self.bus.open()
        self.bus.power_on()
        self.bus.scan()
        self.bus.initial_read()
        if isinstance(self.world, SimWorld):  # the kinematic body learns its legs
            self.world.step(0.0, self.emulator.present_positions())

    def _emit(self, kind: str, message: str, **data: Any) -> None:
        self.events.append((kind, message, data))

    @property
    def ball_play(self) -> Any:
        return self.manager.module("ball")

    # -- the loop --------------------------------------------------------------------------------
    def frame(self) -> JointFrame:
        """One bulk read of the sensors and the frame the daemon makes of it, as a tick starts."""
        self.bus.read_sensors()
        return self.bus.frame(self.tick, self.time, self.tick_s)

    def step(self) -> None:
        """One motion tick, then the physics up to the next one, then vision if it is due."""
        start = self.link.clock_ms
        targets = self.manager.step(self.frame())
        self.bus.write_targets(targets)
        self.emulator.advance(self.tick_s)
        self.link.idle_until(start + self.tick_s * 1000.0)
        self.time += self.tick_s
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

    def calibrated(self, timeout: float = 5.0) -> bool:
        """Step until the gyro centre is measured (motion/gyro_centre.py): fall detection and
        walking wait for it, on the robot as here."""
        imu = self.manager.module("imu")
        return self.run_until(lambda _r: bool(imu.calibrated), timeout)

    def run_until(self, done: Callable[[SimRig], bool], timeout: float) -> bool:
        """Step until ``done(rig)`` (checked every tick) or ``timeout`` simulated seconds."""
        end = self.time + timeout
        while self.time < end:
            if done(self):
                return True
            self.step()
        return done(self)
