"""Which motion modules the daemon runs, in tick order. The one place to add a module."""

from __future__ import annotations

from typing import Any

from config.loader import RobotConfig
from robot_daemon.motion.action.player import ActionModule
from robot_daemon.motion.action.store import PageStore, user_library_dir
from robot_daemon.motion.ball import ball_module
from robot_daemon.motion.behaviours import BehaviourLibrary
from robot_daemon.motion.choreography import ChoreographyModule
from robot_daemon.motion.direct import DirectModule
from robot_daemon.motion.fall import FallMonitor
from robot_daemon.motion.gyro_centre import GyroCalibration
from robot_daemon.motion.head import HeadLimits, HeadModule
from robot_daemon.motion.manager import MotionManager
from robot_daemon.motion.policy import PolicyModule, PolicySettings
from robot_daemon.motion.sound import SoundPlayer
from robot_daemon.motion.walking.gait import WalkingModule
from robot_daemon.motion.walking.params import WalkParams


def build_manager(robot: RobotConfig, settings: dict[str, Any]) -> MotionManager:
    """A manager with every module attached. ``settings`` is the merged config (all sections).

    Order matters: modules later in the list see the same frame but run after earlier ones
    (action, head, walking, as the framework does; direct joint control last). Every module's
    ``observe`` runs before any ``step``: the gyro calibration first (it marks the frame
    calibrated or not), then the fall monitor, so a fall stops the others in the tick it is
    detected."""
    manager = MotionManager(robot)
    imu = settings.get("imu") or {}
    manager.add(GyroCalibration(imu.get("calibration")))
    manager.add(FallMonitor(settings.get("imu"), settings.get("fall")))
    motion = settings.get("motion") or {}
    names = {j.id: j.name for j in robot.joints}
    store = PageStore(names, motion.get("library") or None, user_library_dir(motion))
    manager.add(ActionModule(store.library, store))
    manager.add(HeadModule(HeadLimits.from_config(settings.get("head"))))
    manager.add(WalkingModule(WalkParams.from_config(settings.get("walking"))))
    manager.add(DirectModule(default_speed=float(robot.max_speed) / 2))
    manager.add(PolicyModule(PolicySettings.from_config(settings.get("policy"))))
    manager.add(ball_module(settings))
    choreography = ChoreographyModule(SoundPlayer(settings.get("sound")))
    choreography.behaviours = BehaviourLibrary(settings.get("behaviours"))
    manager.add(choreography)
    return manager
