"""``darwin calibrate``: joint offsets in the user's config.

``darwin calibrate import /darwin/Data/config.ini`` takes the offsets ROBOTIS's own offset tuner
left on the robot (its ``[Offset]`` section) and writes ``[robot.joints.<name>] offset_deg`` to
the user config (``--config FILE``, else ``$DARWIN_CONFIG``, else ``~/.config/darwin/config.toml``).
A running daemon reads them at its next start, or at once through ``Robot.calibration``.
"""

from __future__ import annotations

import argparse

from config.loader import load_robot, robot_from_dict, shipped
from config.robotis_offsets import import_offsets
from config.user_file import set_joint_offsets, target_path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION")
    imp = sub.add_parser(
        "import", help="import ROBOTIS's offsets ([Offset] ID_nn = steps) from its config.ini"
    )
    imp.add_argument(
        "ini",
        metavar="CONFIG_INI",
        help="ROBOTIS's config.ini, e.g. a copy of /darwin/Data/config.ini",
    )
    imp.add_argument("--config", metavar="FILE", help="user config file to write")
    imp.add_argument(
        "--dry-run", action="store_true", help="print the offsets without writing them"
    )


def run(args: argparse.Namespace) -> int:
    target = target_path(args.config)
    # The file is created by the first import: until then the shipped joints are the robot's.
    robot = load_robot(target) if target.exists() else robot_from_dict(shipped()["robot"])
    imported = import_offsets(args.ini, robot)
    for name, deg in imported.degrees.items():
        joint = robot.joint(name)
        print(f"{name}: {deg:+.3f}° (ID_{joint.id:02d} = {imported.steps[joint.id]})")
    for key in imported.ignored:
        print(f"ignored {key}: no joint of this robot has that ID")
    if args.dry_run:
        print(f"dry run: nothing written to {target}")
        return 0
    path = set_joint_offsets(imported.degrees, target)
    print(f"config: {path}")
    return 0
