"""``darwin replay FILE.mcap… [--robot NAME] [--rate 2.0] [--loop]``: republish a recording (or
the segments of a split one, as one) on the key space under a robot name of its own, controllable
on ``…/replay/control``. A recording of several robots plays one of them: ``--source NAME``."""

from __future__ import annotations

import argparse
import sys
import threading

from clients.recording.reader import read_session
from clients.recording.replay import BLOCK_WAIT_US, Replayer, default_robot_name
from clients.robot import TOPICS
from schemas.errors import ProtocolError
from schemas.session import (
    DEFAULT_ENDPOINT,
    ENV_ENDPOINT,
    client_config,
    open_session,
    resolve,
    server_config,
)
from schemas.signals import on_stop_signals


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "file",
        nargs="+",
        help="an MCAP recording made by `darwin record` (or all the segments of a split one)",
    )
    parser.add_argument(
        "--robot", metavar="NAME", help="robot name to publish as (default: <recorded>-replay)"
    )
    parser.add_argument(
        "--source",
        metavar="NAME",
        help="which recorded robot to play, when the file holds several (darwin record --robot "
        "A --robot B)",
    )
    parser.add_argument("--rate", type=float, default=1.0, help="speed factor (1.0 = real time)")
    parser.add_argument("--loop", action="store_true", help="start over at the end, forever")
    parser.add_argument(
        "--stay",
        action="store_true",
        help="keep serving (paused at the end) instead of exiting when the recording ends",
    )
    parser.add_argument("--start", type=float, default=0.0, metavar="S", help="start at S seconds")
    parser.add_argument("--paused", action="store_true", help="start paused (resume via control)")
    parser.add_argument("--topics", nargs="+", metavar="TOPIC", help="replay only these topics")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--listen", metavar="ENDPOINT", help="be a peer listening on ENDPOINT")
    where.add_argument(
        "--connect",
        metavar="ENDPOINT",
        help=f"connect to ENDPOINT (default: {ENV_ENDPOINT}, else {DEFAULT_ENDPOINT})",
    )


def run(args: argparse.Namespace) -> int:
    notices: list[str] = []
    try:
        rec = read_session(args.file, on_notice=notices.append)
    except (OSError, ProtocolError) as exc:
        name = getattr(exc, "filename", None) or " ".join(args.file)
        print(f"darwin replay: cannot read {name}: {exc}", file=sys.stderr)
        return 2
    if not rec.messages:
        hint = f" ({notices[0]})" if notices else ""
        if rec.metadata.get("darwin", {}).get("profile") == "ros2":
            hint = "; it is a ROS 2 bag (darwin record --ros2): play it with `ros2 bag play`"
        print(f"darwin replay: {rec.path} holds no replayable messages{hint}", file=sys.stderr)
        return 2
    topics = [t for item in args.topics for t in item.split(",") if t] if args.topics else None
    unknown = [t for t in topics or () if t not in TOPICS]
    if unknown:
        print(f"darwin replay: unknown topic(s) {unknown}; known: {list(TOPICS)}", file=sys.stderr)
        return 2
    if args.source or len(rec.robots) > 1:
        if not args.source:
            print(
                f"darwin replay: {rec.path} holds several robots ({', '.join(rec.robots)}); "
                "choose one with --source NAME",
                file=sys.stderr,
            )
            return 2
        try:
            rec = rec.only(args.source)
        except ValueError as exc:
            print(f"darwin replay: {exc}", file=sys.stderr)
            return 2
    robot = args.robot or default_robot_name(rec)
    stop = threading.Event()

    on_stop_signals(lambda _signum: stop.set())
    if args.listen:
        conf = server_config([args.listen], block_wait_us=BLOCK_WAIT_US)
        where = f"listening on {args.listen}"
    else:
        endpoint = resolve(args.connect, robot).endpoint
        conf = client_config(endpoint)
        where = f"connected to {endpoint}"
    session = open_session(
        conf,
        "cannot open the Zenoh session for the replay",
        "use --listen ENDPOINT to be reachable yourself, or --connect to a running peer",
    )
    try:
        replayer = Replayer(rec, session, robot, rate=args.rate, loop=args.loop, topics=topics)
        if args.start:
            replayer.seek(args.start)
        replayer.start(paused=args.paused)
        trunc = " (truncated file)" if rec.truncated else ""
        print(
            f"replaying {rec.path}{trunc}: {len(rec.messages)} messages, {rec.duration:.1f} s, "
            f"as robot {robot} at {args.rate:g}x, {where}; control on "
            f"{replayer.keys.replay_control}",
            file=sys.stderr,
            flush=True,
        )
        for line in notices:
            print(f"darwin replay: {line}", file=sys.stderr, flush=True)
        def wait_then_stop() -> None:
            replayer.wait()
            if not args.stay:
                replayer.linger(stop)
                stop.set()

        finished = threading.Thread(target=wait_then_stop, daemon=True)
        finished.start()
        stop.wait()
        status = replayer.status()
        replayer.stop()
    finally:
        session.close()
    print(
        f"replayed {status['published']} messages ({status['loops']} loops), "
        f"ended at {status['position']:.1f} s",
        file=sys.stderr,
        flush=True,
    )
    return 0
