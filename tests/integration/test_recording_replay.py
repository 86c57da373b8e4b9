"""Replay over real Zenoh sessions: a recording made from a loopback publisher is republished
into a fresh key space (in-process and by the `darwin replay` process) and a subscriber gets the
same payloads in the same order; the control queryable pauses, seeks and reports status."""

from __future__ import annotations

import queue
import subprocess
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh

from clients.recording import Recorder, Recording, ReplayControl, Replayer, read_recording
from clients.robot import Robot
from schemas.errors import InvalidCommandError, RobotUnreachableError
from schemas.keys import Keys
from schemas.messages import CameraFrame, Joints, decode, encode
from schemas.session import free_tcp_port, open_client, open_server
from tests.fixtures.emulator import wait_until
from tests.fixtures.system import darwin_command
from tests.integration.test_recording_mcap import (
    ROBOT,
    Source,
    imu_msg,
    joints_msg,
    subscribed,
)


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, list[bytes]]]:
    path = tmp_path_factory.mktemp("replay") / "session.mcap"
    src = Source()
    try:
        with open_client(src.endpoint) as session:
            rec = Recorder(session, path, robot=ROBOT).start()
            subscribed(src)
            src.burst(range(100), every=0.002)
            total = sum(map(len, src.sent.values()))
            wait_until(lambda: rec.stats.total == total, what="recording")
            rec.stop()
    finally:
        src.close()
    return path, src.sent


class Listener:
    """A client subscribed to every topic of one robot name, queueing (topic, payload).
    ``stall``: on its first sample it holds Zenoh's receiving thread that many seconds, as a
    loaded host that does not run the subscriber for a while does."""

    def __init__(self, endpoint: str, robot: str, stall: float = 0.0) -> None:
        self.endpoint = endpoint
        self.session = open_client(endpoint)
        self.got: queue.Queue[tuple[str, bytes]] = queue.Queue()
        self._stall = stall
        self.subs = [
            self.session.declare_subscriber(key, lambda s, t=topic: self._take(t, s))
            for topic, key in Keys(robot).topics().items()
        ]

    def _take(self, topic: str, sample: zenoh.Sample) -> None:
        if self._stall:
            stall, self._stall = self._stall, 0.0
            time.sleep(stall)  # the subscriber not running: the condition under test
        self.got.put((topic, sample.payload.to_bytes()))

    def take(self, n: int, timeout: float = 20.0) -> list[tuple[str, bytes]]:
        return [self.got.get(timeout=timeout) for _ in range(n)]

    def close(self) -> None:
        if not self.session.is_closed():
            self.session.close()


def by_topic(items: list[tuple[str, bytes]]) -> dict[str, list[bytes]]:
    out: dict[str, list[bytes]] = {}
    for topic, payload in items:
        out.setdefault(topic, []).append(payload)
    return out


def darwin_replay(*args: str) -> subprocess.Popen[str]:
    """``darwin replay ARGS --paused`` with its stderr to read."""
    return subprocess.Popen(
        darwin_command("replay", *args, "--paused"), stderr=subprocess.PIPE, text=True
    )


def replay_to_the_end(
    files: list[str],
    robot: str,
    rate: str,
    count: int,
    first_line_ok: Callable[[str], bool],
    timeout: float = 20.0,
    stall: float = 0.0,
) -> tuple[list[tuple[str, bytes]], str, Listener]:
    """``darwin replay`` of ``files`` as ``robot``, resumed from paused and run to its end:
    the ``count`` messages a listener (stalled ``stall`` s at its first sample) got, the
    replay's stderr after its first line (which ``first_line_ok`` checks) and the (closed)
    listener. The replay must exit 0 saying it replayed ``count`` messages."""
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    proc = darwin_replay(*files, "--listen", endpoint, "--robot", robot, "--rate", rate)
    listener = None
    try:
        assert proc.stderr is not None
        line = proc.stderr.readline()
        assert first_line_ok(line), line
        listener = Listener(endpoint, robot, stall)
        ctl = ReplayControl(listener.session, robot, timeout=5.0)
        assert ctl.status()["state"] == "paused"
        assert ctl.resume()["state"] == "playing"
        got = listener.take(count)
        listener.close()  # it has everything: the replay need not wait for it at its end
        _, err = proc.communicate(timeout=timeout)  # exits by itself at the end
        assert proc.returncode == 0, err
        assert f"replayed {count} messages" in err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        if proc.stderr is not None:
            proc.stderr.close()  # also when the replay ended by itself before a failure here
        if listener:
            listener.close()
    return got, err, listener


def test_darwin_replay_republishes_the_same_payloads(recording) -> None:
    path, sent = recording
    total = sum(map(len, sent.values()))
    got, _, listener = replay_to_the_end(
        [str(path)],
        "fresh",
        "4",
        total,
        lambda line: line.startswith("replaying") and "as robot fresh" in line,
    )
    assert by_topic(got) == sent
    assert listener.got.empty()


def record_frames(path: Path, ticks: int, frame_every: int, pace: float) -> dict[str, list[bytes]]:
    """Record joints and IMU every tick and a ~12 kB camera frame every ``frame_every``th, a
    tick every ``pace`` s; returns what was sent, by topic."""
    src = Source()
    rng = np.random.default_rng(3)
    try:
        with open_client(src.endpoint) as session:
            rec = Recorder(session, path, robot=ROBOT).start()
            subscribed(src, ("joints", "imu", "camera"))
            for tick in range(ticks):
                src.put("joints", encode(joints_msg(tick)))
                src.put("imu", encode(imu_msg(tick)))
                if tick % frame_every == 0:
                    jpeg = b"\xff\xd8" + rng.bytes(12_000) + b"\xff\xd9"
                    frame = CameraFrame(jpeg=jpeg, width=320, height=240, seq=tick)
                    src.put("camera", encode(frame))
                if pace:
                    time.sleep(pace)  # pacing a publisher, not synchronising the test
            total = sum(map(len, src.sent.values()))
            wait_until(lambda: rec.stats.total == total, what="recording")
            rec.stop()
    finally:
        src.close()
    return src.sent


# A subscriber a loaded host does not run for a while: its first sample holds Zenoh's receiving
# thread this long (s).
STALL_S = 2.0


def test_a_stalled_subscriber_is_waited_for_while_the_replay_plays(tmp_path: Path) -> None:
    """~6 MB of camera frames, more than the link's queues and socket buffers hold: the replay
    waits for room while the subscriber stalls. With the daemon's session settings a sample
    that may not be dropped waited 0.5 s for room in that subscriber's link queue, then Zenoh
    closed the link and every sample queued for it was lost."""
    path = tmp_path / "frames.mcap"
    sent = record_frames(path, 2000, 4, 0.0)
    total = sum(map(len, sent.values()))
    got, _, _ = replay_to_the_end(
        [str(path)], "slow", "10", total, lambda line: line.startswith("replaying"), stall=STALL_S
    )
    assert by_topic(got) == sent


def test_a_replay_that_ends_waits_for_a_subscriber_still_behind(tmp_path: Path) -> None:
    """~1.2 MB of camera frames in a burst, at 100×: all of it is sent while the subscriber
    stalls, and the replay ends. Closing its session at once took the link down under the
    subscriber before it had read what had been sent."""
    path = tmp_path / "burst.mcap"
    sent = record_frames(path, 300, 3, 0.0)
    total = sum(map(len, sent.values()))
    got, _, _ = replay_to_the_end(
        [str(path)], "behind", "100", total, lambda line: line.startswith("replaying"),
        stall=STALL_S,
    )  # fmt: skip
    assert by_topic(got) == sent


@contextmanager
def paused_replay(
    path: Path, robot: str, **options: Any
) -> Iterator[tuple[Recording, Replayer, Listener, ReplayControl]]:
    """``path`` replayed in this process as ``robot`` (``options`` for the Replayer), started
    paused on a server of its own, with a listener there and the replay's control client."""
    rec = read_recording(path)
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    with open_server([endpoint]) as server:
        listener = Listener(endpoint, robot)
        replayer = Replayer(rec, server, robot, **options).start(paused=True)
        try:
            yield rec, replayer, listener, ReplayControl(listener.session, robot)
        finally:
            replayer.stop()
            listener.close()


def test_control_pause_seek_status_and_bad_requests(recording) -> None:
    path, _ = recording
    with paused_replay(path, "ctl", rate=1.0) as (rec, replayer, listener, ctl):
        st = ctl.status()
        assert st["state"] == "paused" and st["position"] == 0.0
        with Robot(listener.endpoint, "ctl") as viewer:
            assert viewer.alive()  # viewers see the replayed robot as up
        assert st["count"] == len(rec.messages) and st["source_robot"] == ROBOT
        assert st["duration"] == pytest.approx(rec.duration, abs=1e-6)

        # Seek past the middle while paused: nothing is sent until resume, then the rest.
        middle = rec.messages[len(rec.messages) // 2]
        t = (middle.log_ns - rec.start_ns) / 1e9
        st = ctl.seek(t)
        assert st["position"] == pytest.approx(t, abs=1e-6) and st["state"] == "paused"
        assert listener.got.empty()
        rest = [m for m in rec.messages if m.log_ns >= middle.log_ns]
        ctl.rate(20.0)
        ctl.resume()
        got = listener.take(len(rest))
        # Per topic: each topic's subscriber has a callback thread of its own.
        assert by_topic(got) == by_topic([(m.topic, m.payload) for m in rest])
        assert replayer.wait(timeout=20)
        assert ctl.status()["state"] == "finished"

        with pytest.raises(InvalidCommandError, match="outside the recording") as info:
            ctl.seek(rec.duration + 5)
        assert info.value.field == "t"
        with pytest.raises(InvalidCommandError) as info:
            ctl.rate(0)
        assert info.value.field == "rate"
        with pytest.raises(InvalidCommandError, match="unknown op 'jump'"):
            ctl._ask("jump")

        # Seeking a finished replay plays again from there.
        ctl.seek(0.0)
        again = listener.take(len(rec.messages))
        assert by_topic(again) == by_topic([(m.topic, m.payload) for m in rec.messages])


def test_replay_loops(recording) -> None:
    path, _ = recording
    looped = paused_replay(path, "looped", rate=50.0, loop=True, topics=["joints"])
    with looped as (rec, _, listener, ctl):
        ctl.status()  # our subscriptions are declared before this round trip completes
        ctl.resume()
        n = len(rec.topic("joints"))
        got = listener.take(2 * n + 1)
        ticks = [decode(p, Joints).tick for _, p in got]
        assert ticks == [*range(n), *range(n), 0]
        assert ctl.status()["loops"] >= 2


def test_control_without_replay_says_what_to_run() -> None:
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    with open_server([endpoint]) as server:
        ctl = ReplayControl(server, "nobody", timeout=0.5)
        started = time.monotonic()
        with pytest.raises(RobotUnreachableError, match="darwin replay"):
            ctl.status()
        assert time.monotonic() - started < 10
