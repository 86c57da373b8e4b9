"""The simulated world: the robot's pose from its own legs, falls, a ball, the camera image."""
