"""The robot's own ``darwin`` commands (the daemon, its launchers and its maintenance tools),
declared for :mod:`schemas.registry` like every other package's."""

from __future__ import annotations

from schemas.registry import Command

COMMANDS = (
    Command(
        "up",
        "robot_daemon.launch.up",
        "start emulator (or --port), daemon and gateway in one command",
        10,
    ),
    Command(
        "daemon",
        "robot_daemon.launch.daemon_cli",
        "run the robot daemon (owns the bus, publishes, arbiter)",
        20,
    ),
    Command(
        "router",
        "robot_daemon.launch.router",
        "a Zenoh router: the meeting point of a fleet of robots",
        30,
    ),
    Command(
        "sim", "robot_daemon.plant.sim_cli", "run the hardware emulator on a pseudo-terminal", 50
    ),
    Command(
        "scan",
        "robot_daemon.bus.scan",
        "list every device on a serial port (ID, model, firmware)",
        60,
    ),
    Command(
        "doctor",
        "robot_daemon.doctor.cli",
        "check the robot: port, bus, servos, power, loop, Zenoh",
        70,
    ),
    Command(
        "servo",
        "robot_daemon.launch.servo_cli",
        "servo maintenance: give a new servo its ID and settings",
        90,
    ),
    Command(
        "motion", "robot_daemon.motion.cli", "motion files: convert between .bin and text", 140
    ),
    Command(
        "users",
        "robot_daemon.security.users_cli",
        "manage identities and roles (add/remove/list)",
        200,
    ),
    Command(
        "certs",
        "robot_daemon.security.certs_cli",
        "create TLS certificates: CA, robot, clients",
        210,
    ),
    Command(
        "service",
        "robot_daemon.launch.service_cli",
        "start the daemon at boot: systemd units, udev rule",
        220,
    ),
)
