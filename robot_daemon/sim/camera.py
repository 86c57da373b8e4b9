"""The ``sim`` camera source (imported by the daemon's source registry; lives with the world)."""

from robot_daemon.sim.world.camera_source import SimCameraSource

__all__ = ["SimCameraSource"]
