"""Replay fidelity: how closely does ``darwin replay`` reproduce a recording's timing?

A peer publishes like the daemon (joints and IMU every 8 ms, status at 10 Hz, ~12 kB camera
frames at 30 Hz) for a few seconds; a :class:`Recorder` writes it to MCAP while a live subscriber
notes arrival times. The recording is then replayed by a :class:`Replayer` into a fresh key space
at each rate, and a subscriber notes arrival times again.

Figures (milliseconds):
* live jitter (the baseline): arrival offset vs. the publisher's own schedule, as the recorder's
  neighbour saw it;
* replay timing error: arrival offset of each replayed message vs. its recorded ``log_time``
  (scaled by the rate), after removing the constant start offset;
and the ratio replay error / live jitter at p50 and p99. Content is checked too (payloads equal,
per topic). Last, the recording cut at 90 % is rewritten by ``darwin record recover``'s
``recover()``, timed against ``read_recording`` of the same cut file.
Run: ``.venv/bin/python benchmarks/replay_benchmark.py [--seconds 5] [--rates 1 2]``
"""

from __future__ import annotations

import argparse
import os
import queue
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # for tests.integration

from clients.recording import Recorder, Replayer, read_recording
from clients.recording.recover import recover
from schemas.keys import Keys
from schemas.messages import CameraFrame, Joints, Status, decode, encode
from schemas.qos import for_key
from schemas.session import free_tcp_port, open_client, open_server
from tests.integration.test_recording_mcap import imu_msg, joints_msg

TICK = 0.008


def joints(tick: int) -> bytes:
    return encode(joints_msg(tick))


def imu(tick: int) -> bytes:
    return encode(imu_msg(tick))


def camera(seq: int, rng: np.random.Generator) -> bytes:
    jpeg = b"\xff\xd8" + rng.bytes(12_000) + b"\xff\xd9"
    return encode(CameraFrame(jpeg=jpeg, width=320, height=240, seq=seq))


def percentiles(values: list[float]) -> tuple[float, float, float]:
    a = np.abs(np.asarray(values)) * 1e3
    return float(np.percentile(a, 50)), float(np.percentile(a, 99)), float(a.max())


class Listener:
    def __init__(self, endpoint: str, robot: str) -> None:
        self.session = open_client(endpoint)
        self.got: queue.Queue[tuple[str, int, bytes]] = queue.Queue()
        self.subs = [
            self.session.declare_subscriber(key, self._cb(topic))
            for topic, key in Keys(robot).topics().items()
        ]

    def _cb(self, topic: str) -> Callable[..., None]:
        return lambda s: self.got.put((topic, time.monotonic_ns(), s.payload.to_bytes()))

    def drain(self, n: int, timeout: float) -> list[tuple[str, int, bytes]]:
        out = []
        deadline = time.monotonic() + timeout
        while len(out) < n and time.monotonic() < deadline:
            try:
                out.append(self.got.get(timeout=0.5))
            except queue.Empty:
                continue
        return out

    def close(self) -> None:
        self.session.close()


def wait_matching(pub, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not pub.matching_status.matching:
        if time.monotonic() > deadline:
            raise SystemExit("no subscriber matched the publisher: is loopback TCP blocked?")
        time.sleep(0.01)


def record(seconds: float, path: str) -> tuple[list[float], int]:
    """Publish and record; return the live arrival offsets (s) vs. schedule and the count."""
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    keys = Keys("bench")
    rng = np.random.default_rng(1)
    with open_server([endpoint]) as robot, open_client(endpoint) as rec_session:
        pubs = {
            t: robot.declare_publisher(k, **for_key(k).kwargs()) for t, k in keys.topics().items()
        }
        live = Listener(endpoint, "bench")
        rec = Recorder(rec_session, path, robot="bench", flush_interval=0.5).start()
        wait_matching(pubs["joints"])
        time.sleep(0.5)  # let every topic's routes settle before the measured run
        schedule: dict[tuple[str, int], int] = {}
        start = time.monotonic_ns()
        ticks = int(seconds / TICK)
        sent = 0
        for tick in range(ticks):
            due = start + int(tick * TICK * 1e9)
            delay = (due - time.monotonic_ns()) / 1e9
            if delay > 0:
                time.sleep(delay)  # the publisher's own 8 ms pacing
            pubs["joints"].put(joints(tick))
            pubs["imu"].put(imu(tick))
            schedule[("joints", tick)] = due
            sent += 2
            if tick % 12 == 0:
                pubs["status"].put(encode(Status(state="running", robot="bench")))
                sent += 1
            if tick % 4 == 0:
                pubs["camera"].put(camera(tick, rng))
                sent += 1
        got = live.drain(sent, timeout=10)
        deadline = time.monotonic() + 10
        while rec.stats.total < sent and time.monotonic() < deadline:
            time.sleep(0.05)
        stats = rec.stop()
        live.close()
        print(
            f"recorded {stats.total}/{sent} messages in {stats.duration:.1f} s "
            f"({stats.dropped} dropped)"
        )
    arrivals = {}
    for topic, t, payload in got:
        if topic == "joints":
            arrivals[decode(payload, Joints).tick] = t
    offsets = [(arrivals[k] - schedule[("joints", k)]) / 1e9 for k in sorted(arrivals)]
    base = statistics.median(offsets)
    return [o - base for o in offsets], sent


def replay(path: str, rate: float) -> tuple[list[float], bool, float]:
    rec = read_recording(path)
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    with open_server([endpoint]) as server:
        listener = Listener(endpoint, "fresh")
        replayer = Replayer(rec, server, "fresh", rate=rate).start(paused=True)
        deadline = time.monotonic() + 10
        while not replayer.watched("joints") and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.5)
        t0 = time.monotonic()
        replayer.resume()
        got = listener.drain(len(rec.messages), timeout=rec.duration / rate + 10)
        wall = time.monotonic() - t0
        replayer.stop()
        listener.close()
    by_topic_got: dict[str, list[bytes]] = {}
    for topic, _, payload in got:
        by_topic_got.setdefault(topic, []).append(payload)
    by_topic_rec: dict[str, list[bytes]] = {}
    for m in rec.messages:
        by_topic_rec.setdefault(m.topic, []).append(m.payload)
    same = by_topic_got == by_topic_rec
    # Match joints arrivals to their recorded log times by order (per-topic order is kept).
    rec_joints = [m.log_ns for m in rec.messages if m.topic == "joints"]
    got_joints = [t for topic, t, _ in got if topic == "joints"]
    errors = [
        (g - got_joints[0]) / 1e9 - (r - rec_joints[0]) / 1e9 / rate
        for g, r in zip(got_joints, rec_joints, strict=False)
    ]
    base = statistics.median(errors)
    return [e - base for e in errors], same, wall


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=5.0, help="length of the recording")
    ap.add_argument("--rates", type=float, nargs="+", default=[1.0, 2.0, 10.0])
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "bench.mcap")
        live, _ = record(args.seconds, path)
        size = os.path.getsize(path)
        rec = read_recording(path)
        print(f"file {size / 1e6:.2f} MB, {len(rec.messages)} messages over {rec.duration:.2f} s")
        lp50, lp99, lmax = percentiles(live)
        print(f"{'':28}{'p50 ms':>9}{'p99 ms':>9}{'max ms':>9}")
        print(f"{'live jitter (baseline)':28}{lp50:9.3f}{lp99:9.3f}{lmax:9.3f}")
        for rate in args.rates:
            errors, same, wall = replay(path, rate)
            p50, p99, mx = percentiles(errors)
            label = f"replay x{rate:g} timing error"
            print(
                f"{label:28}{p50:9.3f}{p99:9.3f}{mx:9.3f}   ratio p50 {p50 / lp50:5.2f}, "
                f"p99 {p99 / lp99:5.2f}; wall {wall:.2f} s for {rec.duration / rate:.2f} s; "
                f"content {'identical' if same else 'DIFFERS'}"
            )
        recover_figures(path, tmp)
    return 0


def recover_figures(path: str, tmp: str) -> None:
    """Cut the recording at 90 % (a killed recorder) and time ``recover`` against reading the
    same cut file with ``read_recording`` (the baseline: the same walk, no writing)."""
    data = Path(path).read_bytes()
    cut = os.path.join(tmp, "cut.mcap")
    Path(cut).write_bytes(data[: len(data) * 9 // 10])
    t0 = time.perf_counter()
    read = read_recording(cut, on_notice=lambda line: None)
    t_read = time.perf_counter() - t0
    t0 = time.perf_counter()
    result = recover(cut, os.path.join(tmp, "cut.recovered.mcap"))
    t_recover = time.perf_counter() - t0
    mb = len(data) * 0.9 / 1e6
    print(
        f"recover of a file cut at 90 % ({mb:.2f} MB): {t_recover:.3f} s ({mb / t_recover:.1f} "
        f"MB/s), {result.total} messages kept; read_recording of it (baseline) {t_read:.3f} s "
        f"for {len(read.messages)} msgpack messages; ratio {t_recover / t_read:.2f}"
    )


if __name__ == "__main__":
    sys.exit(main())
