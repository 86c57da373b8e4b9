"""``darwin list [--connect ENDPOINT] [--json]``: every live robot reachable there (a router's
endpoint lists the whole fleet), one line each — ``name: endpoint`` then its state, lease
holder, battery, alarms and loop rate — or a JSON list of the same records."""

from __future__ import annotations

import argparse
import json
import sys

from clients.fleet import STATUS_WAIT_S, discover_at
from schemas.keys import check_robot_name
from schemas.session import add_target_arguments, credentials_from_args, resolve


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_target_arguments(parser)
    parser.set_defaults(robot=None)
    parser.add_argument("--json", action="store_true", help="print a JSON list of records")
    parser.add_argument(
        "--wait",
        type=float,
        default=STATUS_WAIT_S,
        metavar="S",
        help=f"how long to wait for each robot's status ({STATUS_WAIT_S:g} s)",
    )


def run(args: argparse.Namespace) -> int:
    # --robot here narrows the list to one name; without it, every robot.
    target = resolve(args.connect, None, credentials_from_args(args))
    endpoint = target.endpoint
    pattern = check_robot_name(args.robot) if args.robot else "*"
    records = discover_at(endpoint, max(0.0, args.wait), pattern, target.credentials)
    if args.json:
        print(json.dumps([r.to_dict() for r in records], indent=2))
    elif not records:
        print(
            f"darwin list: no live robot at {endpoint}; start one with `darwin up` (or "
            "`darwin up --router ENDPOINT --robot NAME` to join a router)",
            file=sys.stderr,
        )
    else:
        for r in records:
            print(r.line(), flush=True)
    return 0
