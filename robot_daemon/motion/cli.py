"""``darwin motion``: action files. ``convert IN OUT`` between the ROBOTIS ``.bin`` and the
project's text format (any other extension; a directory reads every ``*.toml`` in it), and
``list FILE`` to see the pages. The format of each side is chosen by its extension.
``export OUT.bin`` writes the library the daemon plays (shipped pages with the user's own on
top) as one ROBOTIS ``.bin``, refusing pages the format cannot hold."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from robot_daemon.motion.action import binfile, textfile
from robot_daemon.motion.action.library import LIBRARY_DIR, MotionLibrary, read_pages


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True)
    conv = sub.add_parser("convert", help="convert between .bin and text (by extension)")
    conv.add_argument("input", help="a .bin file, a text file, or a directory of text files")
    conv.add_argument("output", help="a .bin file or a text file (.toml)")
    conv.add_argument("--force", action="store_true", help="overwrite OUTPUT if it exists")
    show = sub.add_parser("list", help="list the pages of a motion file or directory")
    show.add_argument("input", nargs="?", default=str(LIBRARY_DIR), help="default: the library")
    export = sub.add_parser("export", help="the daemon's library (shipped + user) as a .bin")
    export.add_argument("output", help="the .bin file to write")
    export.add_argument("--user-library", help="user pages folder (default: as the daemon)")
    export.add_argument("--force", action="store_true", help="overwrite OUTPUT if it exists")


def export(args: argparse.Namespace) -> int:
    from config.loader import load_all, load_robot
    from robot_daemon.motion.action.check import bin_problems
    from robot_daemon.motion.action.store import PageStore, user_library_dir

    dst = Path(args.output)
    if dst.exists() and not args.force:
        print(f"darwin motion: {dst} exists; use --force to overwrite it", file=sys.stderr)
        return 1
    motion = load_all().get("motion") or {}
    names = {j.id: j.name for j in load_robot().joints}
    user = args.user_library or user_library_dir(motion)
    store = PageStore(names, motion.get("library") or None, user)
    for problem in store.problems:
        print(f"darwin motion: {problem}", file=sys.stderr)
    bad = bin_problems(store.library.pages.values())
    if bad:
        print(f"darwin motion: cannot export to .bin: {bad[0]}", file=sys.stderr)
        return 1
    binfile.write_bin(dst, store.library.pages)
    print(f"{dst}: {len(store.library)} pages (user library {store.user_dir})")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.action == "export":
        return export(args)
    if args.action == "list":
        lib = MotionLibrary(read_pages(args.input))
        for row in lib.listing():
            chain = f" → {row['next']}" if row["next"] else ""
            print(f"{row['page']:>3}  {row['name']:<16} {row['steps']} steps{chain}")
        return 0
    src, dst = Path(args.input), Path(args.output)
    if dst.exists() and not args.force:
        print(f"darwin motion: {dst} exists; use --force to overwrite it", file=sys.stderr)
        return 1
    pages = read_pages(src)
    if dst.suffix.lower() == ".bin":
        binfile.write_bin(dst, pages)
    else:
        textfile.write_text(dst, pages)
    kept = sum(1 for p in pages if not p.zero and not p.blank)
    print(f"{src} → {dst}: {kept} pages")
    return 0
