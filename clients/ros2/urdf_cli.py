"""``darwin urdf``: the robot's URDF, generated from the body description and the config."""

from __future__ import annotations

import argparse
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-o", "--output", metavar="FILE", help="write here instead of stdout")
    parser.add_argument("--config", help="user config file (TOML) with the robot's joints")


def run(args: argparse.Namespace) -> int:
    from config.loader import load_robot
    from schemas.body import build_body, limits_from_config
    from schemas.urdf import to_urdf

    robot = load_robot(args.config)
    text = to_urdf(build_body(limits_from_config(robot), robot.max_speed))
    if args.output:
        try:
            with open(args.output, "w", encoding="utf-8") as f:
                f.write(text)
        except OSError as exc:
            print(f"darwin urdf: cannot write {args.output}: {exc.strerror}", file=sys.stderr)
            return 1
        print(f"urdf: {args.output}", flush=True)
    else:
        sys.stdout.write(text)
    return 0
