"""The simulated world behind the emulator: the robot's pose from its own legs, falls, a ball, the
camera image (kinematic), or the MuJoCo plant (:mod:`robot_daemon.plant.physics`).

It plugs into the emulator's seam (:mod:`robot_daemon.emulator`: physics hooks, control ops);
the emulator never imports it. ``sim_cli`` (``darwin sim``) composes the two.
"""
