"""The engine: the daemon that owns the bus and composes the arbiter, the motion manager, the
publishers, the camera and the Zenoh session. Imported by the launchers
(:mod:`robot_daemon.launch`), never the other way round."""
