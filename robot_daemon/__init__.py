"""The robot daemon: owns the CM-730 bus and the camera, runs the motion loop, serves Zenoh."""
