"""``darwin record -o FILE.mcap [--topics …] [--split-seconds N] [--split-bytes N]``: record the
robot's publications until Ctrl-C, SIGTERM or ``--duration``; the file (or every segment) is
closed complete and valid in every case but SIGKILL, which loses at most the last flush interval.

``darwin record --lerobot DIR [--task T] [--fps N] [--no-camera]``: a LeRobotDataset v3 of the
policy stream (:mod:`clients.learn.live_record`); Enter or the ``episode`` op ends an episode.

``darwin record recover FILE [-o OUT]``: rewrite a truncated or damaged recording as a complete,
indexed MCAP (:mod:`clients.recording.recover`).
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
from collections.abc import Callable

import zenoh

from clients.protocol_watch import check_at
from clients.recording.mcap_sink import CHUNK_BYTES
from clients.recording.profiles import PROFILES, get_profile
from clients.recording.recorder import (
    DEFAULT_TOPICS,
    FORMATS,
    Recorder,
    check_options,
    check_robots,
    check_topics,
)
from clients.robot import TOPICS
from schemas.errors import ClientError, IncompatibleProtocolError
from schemas.keys import Keys
from schemas.session import add_target_arguments, connect, credentials_from_args, resolve
from schemas.signals import on_stop_signals


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.usage = (
        "%(prog)s -o FILE.mcap [options]\n"
        "       %(prog)s --lerobot DIR [--task TEXT] [--fps N] [--no-camera] [options]\n"
        "       %(prog)s recover FILE [-o OUT] [--force | --in-place]"
    )
    parser.add_argument("-o", "--output", help="file to write (.mcap or .txt)")
    parser.add_argument(
        "--lerobot",
        metavar="DIR",
        help="write a LeRobotDataset v3 of the policy stream into DIR (a new directory); "
        "Enter on this terminal or the `episode` op on …/record/control ends an episode",
    )
    parser.add_argument("--task", default="", help="with --lerobot: the episodes' task text")
    parser.add_argument(
        "--fps", type=float, default=50.0, help="with --lerobot: frames per second (50)"
    )
    parser.add_argument(
        "--no-camera",
        dest="camera",
        action="store_false",
        help="with --lerobot: no observation.images video, even when the robot has a camera",
    )
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
    parser.add_argument(
        "--profile",
        choices=sorted(PROFILES),
        default="darwin",
        help="what to record and how to encode it (darwin: JSON + msgpack channels; "
        "ros2: a ROS 2 bag, the adapter's topics in CDR as rosbag2 writes them)",
    )
    parser.add_argument(
        "--ros2",
        dest="profile",
        action="store_const",
        const="ros2",
        help="write a ROS 2 bag (same as --profile ros2): `ros2 bag info FILE.mcap` opens it",
    )
    # `--robot A --robot B` or `--robot '*'`: several robots into one file.
    add_target_arguments(parser, several=True)
    parser.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    parser.add_argument(
        "--flush",
        type=float,
        default=0.5,
        metavar="S",
        help="write and fsync what is buffered every S s: the most a kill loses (0.5)",
    )
    parser.add_argument(
        "--chunk-bytes",
        type=int,
        default=CHUNK_BYTES,
        metavar="N",
        help=f"close an MCAP chunk at N uncompressed bytes even between flushes ({CHUNK_BYTES})",
    )
    parser.add_argument(
        "--split-seconds",
        type=float,
        metavar="N",
        help="write segments FILE-0001.mcap, FILE-0002.mcap… of N seconds each",
    )
    parser.add_argument(
        "--split-bytes",
        type=int,
        metavar="N",
        help="write segments of about N bytes each (with --split-seconds: whichever comes first)",
    )
    sub = parser.add_subparsers(dest="action", metavar="recover", title="actions")
    fix = sub.add_parser(
        "recover",
        help="rewrite a truncated recording as a complete, indexed MCAP",
        description="Rewrite a truncated or damaged recording (a killed recorder) as a complete, "
        "indexed MCAP with every message that reached the disk; report what was kept and where "
        "the file was cut.",
    )
    fix.add_argument("file", help="the truncated recording")
    fix.add_argument(
        "-o",
        "--output",
        dest="recovered",
        metavar="OUT",
        help="where to write (default: FILE with .recovered.mcap)",
    )
    fix.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    fix.add_argument(
        "--in-place", action="store_true", help="replace FILE itself with the recovered file"
    )


def run(args: argparse.Namespace) -> int:
    if args.action == "recover":
        return run_recover(args)
    return run_record(args)


def run_recover(args: argparse.Namespace) -> int:
    from clients.recording.recover import RecoverError, recover

    output = args.file if args.in_place else args.recovered
    try:
        result = recover(args.file, output, overwrite=args.force or args.in_place)
    except RecoverError as exc:
        print(f"darwin record recover: {exc}", file=sys.stderr)
        return 2
    print("\n".join(result.lines()), flush=True)
    return 0


def _check(args: argparse.Namespace) -> str:
    """The first thing wrong with the options, or ""."""
    if args.duration is not None and args.duration <= 0:
        return f"--duration {args.duration} must be > 0"
    if args.lerobot:
        if args.output:
            return "give either -o FILE.mcap or --lerobot DIR, not both (run two recorders)"
        if os.path.exists(os.path.join(args.lerobot, "meta", "info.json")):
            return f"{args.lerobot} already holds a dataset: choose another directory"
        if not 1.0 <= args.fps <= 125.0:
            return f"--fps {args.fps} must be within 1..125 (the policy loop's rates)"
        return ""
    if not args.output:
        return "give the file to write with -o FILE.mcap (or: darwin record recover FILE)"
    folder = os.path.dirname(os.path.abspath(args.output))
    if not os.path.isdir(folder):
        return f"cannot write {args.output}: no folder {folder}"
    return ""


def run_record(args: argparse.Namespace) -> int:
    topics = [t for item in args.topics for t in item.split(",") if t] if args.topics else None
    problem = _check(args)
    try:
        profile = get_profile(args.profile)
        topics = check_topics(topics, profile)
        check_options(args.flush, args.chunk_bytes, args.split_seconds, args.split_bytes)
    except ValueError as exc:
        problem = problem or str(exc)
    if problem:
        print(f"darwin record: {problem}", file=sys.stderr)
        return 2
    robots = args.robot or []
    several = len(robots) > 1 or "*" in robots
    if args.lerobot and several:
        print("darwin record: --lerobot records one robot: give one --robot", file=sys.stderr)
        return 2
    try:
        target = resolve(
            args.connect,
            None if several or not robots else robots[0],
            credentials_from_args(args),
        )
        chosen = check_robots(robots) if several else None
    except ValueError as exc:
        print(f"darwin record: {exc}", file=sys.stderr)
        return 2
    stop = threading.Event()

    def notice(line: str) -> None:
        print(f"darwin record: {line}", file=sys.stderr, flush=True)

    on_stop_signals(lambda _signum: stop.set())
    session = connect(target)
    try:
        try:
            skew = check_at(session, Keys(target.robot), "darwin record", 3.0)
        except IncompatibleProtocolError:
            session.close()
            raise
        if skew:
            notice(skew)
        if args.lerobot:
            return _record_lerobot(args, session, Keys(target.robot), stop, notice)
        try:
            rec = Recorder(
                session,
                args.output,
                topics,
                robot=target.robot,
                format=args.format,
                flush_interval=args.flush,
                chunk_bytes=args.chunk_bytes,
                split_seconds=args.split_seconds,
                split_bytes=args.split_bytes,
                profile=profile,
                on_notice=notice,
                robots=chosen,
            )
        except ValueError as exc:  # e.g. several robots with the ros2 profile
            print(f"darwin record: {exc}", file=sys.stderr)
            return 2
        who = ", ".join(chosen) if chosen else target.robot
        try:
            rec.start()
        except OSError as exc:
            print(
                f"darwin record: cannot write {args.output}: {exc.strerror or exc}", file=sys.stderr
            )
            return 2
        except ClientError as exc:
            print(f"darwin record: {exc}", file=sys.stderr)
            return 2
        where = rec.path
        if rec.splitting:
            where = f"{rec.stats.segments[0]} and on"
        print(
            f"recording {who} at {target.endpoint} → {where} ({rec.format}: "
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


def _record_lerobot(
    args: argparse.Namespace,
    session: zenoh.Session,
    keys: Keys,
    stop: threading.Event,
    notice: Callable[[str], None],
) -> int:
    from clients.learn.live_record import LiveRecorder

    try:
        rec = LiveRecorder(
            session, keys, args.lerobot, fps=args.fps, task=args.task, camera=args.camera,
            on_notice=notice,
        ).start()  # fmt: skip
    except OSError as exc:
        print(f"darwin record: cannot write {args.lerobot}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    print(
        f"recording {keys.robot}'s policy stream → {args.lerobot} (LeRobotDataset v3, "
        f"{args.fps:g} fps); Enter ends an episode, Ctrl-C the recording",
        file=sys.stderr,
        flush=True,
    )

    def episodes_from_keys() -> None:
        for line in sys.stdin:
            task = line.strip() or None  # a line with text: the next episode's task
            rec.new_episode(task)

    if sys.stdin is not None and not sys.stdin.closed:
        threading.Thread(target=episodes_from_keys, name="episode-keys", daemon=True).start()
    stop.wait(args.duration)
    stats = rec.stop()
    print(stats.summary(rec.root), file=sys.stderr, flush=True)
    return 0
