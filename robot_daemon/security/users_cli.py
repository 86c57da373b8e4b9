"""`darwin users add NAME --role R --password-file F` / `remove NAME` / `list`: the identities
file (``--users FILE``, default ``~/.config/darwin/users.toml``; see ``users.py``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from robot_daemon.security import users
from schemas.roles import LADDER, Role


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--users", metavar="FILE", help=f"identities file (default {users.default_users_file()})"
    )
    sub = parser.add_subparsers(dest="action", required=True)
    add = sub.add_parser("add", help="add a user, or change one's role or password")
    add.add_argument("name")
    add.add_argument("--role", required=True, help=f"one of {', '.join(Role)}")
    secret = add.add_mutually_exclusive_group(required=True)
    secret.add_argument("--password-file", metavar="F", help="file holding the password")
    secret.add_argument(
        "--cert-only", action="store_true", help="no password: the user logs in with a "
        "client certificate (`darwin certs --client NAME`, `darwin up --secure --mtls`)"
    )
    rm = sub.add_parser("remove", help="remove a user")
    rm.add_argument("name")
    sub.add_parser("list", help="list users and roles (never passwords)")
    for p in sub.choices.values():  # --users also after the action, where people type it
        p.add_argument("--users", metavar="FILE", default=argparse.SUPPRESS)


def run(args: argparse.Namespace) -> int:
    path = Path(args.users) if args.users else users.default_users_file()
    try:
        if args.action == "add":
            password = (
                None if args.cert_only else users.read_password_file(Path(args.password_file))
            )
            user = users.add(path, args.name, args.role, password)
            print(f"user: {user.name} ({user.role}) in {path}")
        elif args.action == "remove":
            users.remove(path, args.name)
            print(f"removed: {args.name} from {path}")
        else:
            known = users.load(path, must_exist=False)
            order = {r: i for i, r in enumerate((*LADDER, Role.ROBOT))}
            for user in sorted(known.values(), key=lambda u: (order[u.role], u.name)):
                how = "password" if user.password is not None else "certificate"
                print(f"{user.name}: {user.role} ({how})")
            if not known:
                print(f"nobody in {path}", file=sys.stderr)
    except ValueError as exc:
        print(f"darwin users: {exc}", file=sys.stderr)
        return 2
    return 0
