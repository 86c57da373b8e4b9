"""``darwin record -o FILE.mcap [--topics …]``: record the robot's publications until Ctrl-C,
SIGTERM or ``--duration``; the file is closed complete and valid in every case."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from types import FrameType

import zenoh

from clients.recording.recorder import DEFAULT_TOPICS, FORMATS, Recorder, check_topics
from clients.robot import TOPICS
from schemas.errors import RobotUnreachableError
from schemas.session import open_client, resolve


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-o", "--output", required=True, help="file to write (.mcap or .txt)")
    parser.add_argument(
        "--topics",
        nargs="+",
        metavar="TOPIC",
        help=f"topics to record (default: {' '.join(DEFAULT_TOPICS)}; known: {' '.join(TOPICS)})",
    )
    parser.add_argument(
        "--format",
        choices=FORMATS,
        help="mcap (default; .txt/.log files default to text) or the original's plain-text log",
    )
    parser.add_argument("--connect", metavar="ENDPOINT", help="Zenoh endpoint (DARWIN_ENDPOINT)")
    parser.add_argument("--robot", metavar="NAME", help="robot name (DARWIN_ROBOT, default op1)")
    parser.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    parser.add_argument(
        "--flush", type=float, default=0.5, metavar="S", help="flush to disk every S s (0.5)"
    )


def run(args: argparse.Namespace) -> int:
    topics = [t for item in args.topics for t in item.split(",") if t] if args.topics else None
    try:
        topics = check_topics(topics)
    except ValueError as exc:
        print(f"darwin record: {exc}", file=sys.stderr)
        return 2
    if args.duration is not None and args.duration <= 0:
        print(f"darwin record: --duration {args.duration} must be > 0", file=sys.stderr)
        return 2
    folder = os.path.dirname(os.path.abspath(args.output))
    if not os.path.isdir(folder):
        print(f"darwin record: cannot write {args.output}: no folder {folder}", file=sys.stderr)
        return 2
    target = resolve(args.connect, args.robot)
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    try:
        session = open_client(target.endpoint)
    except zenoh.ZError as exc:
        raise RobotUnreachableError(
            f"cannot open a Zenoh session to {target.endpoint}: {exc}. "
            "Is the daemon running (`darwin up`)? Check --connect / DARWIN_ENDPOINT."
        ) from exc
    try:
        rec = Recorder(
            session,
            args.output,
            topics,
            robot=target.robot,
            format=args.format,
            flush_interval=args.flush,
        )
        try:
            rec.start()
        except OSError as exc:
            print(
                f"darwin record: cannot write {args.output}: {exc.strerror or exc}", file=sys.stderr
            )
            return 2
        print(
            f"recording {target.robot} at {target.endpoint} → {rec.path} ({rec.format}: "
            f"{' '.join(rec.topics)}); Ctrl-C to stop",
            file=sys.stderr,
            flush=True,
        )
        stop.wait(args.duration)
        stats = rec.stop()
    finally:
        session.close()
    print(stats.summary(), file=sys.stderr, flush=True)
    return 0
