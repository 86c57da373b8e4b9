"""The clients' ``darwin`` commands, and the ones ``darwin up`` can start next to the robot
(the ROS 2, Foxglove and web adapters; the terminal UI of ``--tui``), declared for
:mod:`schemas.registry` (the launcher names no adapter). Importing this imports nothing of
the clients themselves."""

from __future__ import annotations

from schemas.registry import Adapter, Command

COMMANDS = (
    Command(
        "list", "clients.fleet_cli", "list every live robot (name, endpoint, lease, battery…)", 40
    ),
    Command(
        "calibrate",
        "clients.calibrate_cli",
        "joint offsets: import ROBOTIS's config.ini offsets",
        80,
    ),
    Command("tui", "clients.tui.cli", "the terminal UI (works over SSH)", 110),
    Command("web", "clients.web.cli", "serve the terminal UI to web browsers", 120),
    Command(
        "foxglove",
        "clients.foxglove.cli",
        "a Foxglove WebSocket server: 3D robot, camera, plots",
        130,
    ),
    Command(
        "record", "clients.recording.record_cli", "record the robot's publications to MCAP", 150
    ),
    Command(
        "replay", "clients.recording.replay_cli", "republish a recording on the key space", 160
    ),
    Command(
        "ros2",
        "clients.ros2.cli",
        "make the robot a ROS 2 node (rmw_zenoh, no ROS install needed)",
        170,
    ),
    Command(
        "policy",
        "clients.learn.runner",
        "run a policy (ONNX or Python) on the robot or simulator",
        180,
    ),
    Command(
        "urdf", "clients.ros2.urdf_cli", "print the robot's URDF (from the body description)", 190
    ),
)

ADAPTERS = (
    Adapter("ros2", "also run the ROS 2 adapter (`darwin ros2`)", 20),
    Adapter(
        "foxglove",
        "also start the Foxglove server (darwin foxglove)",
        30,
        listen_help="where Foxglove connects",
    ),
    Adapter(
        "web",
        "also serve the terminal UI to browsers (darwin web)",
        40,
        listen_help="where browsers connect",
    ),
    Adapter("tui", "open the terminal UI here once everything runs", 90, ui=True),
)
