"""Recording the real system (`darwin up` on the emulator) while the robot walks, reading it back
with the `mcap` library, and replaying it into a fresh key space that a Robot client reads as
live."""

from __future__ import annotations

import queue
import threading
from pathlib import Path

from clients.recording import Recorder, ReplayControl, Replayer, read_recording
from clients.robot import Robot
from schemas.messages import Imu, Joints
from schemas.session import free_tcp_port, open_server
from tests.fixtures.mcap import finished_file, summary_counts
from tests.fixtures.system import RunningSystem
from tests.integration.test_motion_system import WAIT

TOPICS = ["joints", "imu", "status", "events"]


def test_record_walk_then_replay_as_live(robot_system: RunningSystem, tmp_path: Path) -> None:
    path = tmp_path / "walk.mcap"
    seen: dict[str, list[float]] = {t: [] for t in TOPICS}
    heard = threading.Condition()

    def witness(topic: str, stamp: float) -> None:
        with heard:
            seen[topic].append(stamp)
            heard.notify_all()

    with robot_system.robot_client(name="recording test") as robot:
        robot.wait_for("joints", timeout=15)
        # A witness on the same session gets every sample the recorder gets.
        witnesses = [robot.subscribe(t, lambda m, t=t: witness(t, m.stamp)) for t in TOPICS]
        rec = Recorder(robot, path, TOPICS).start()
        with robot.control("recording test"):
            robot.walk(x=0.02)
            try:
                robot.stream("imu", seconds=1.5)  # walk for a while
            finally:
                robot.walk_stop()
        stats = rec.stop()
        back = read_recording(path)
        # Zenoh hands a sample to the session's subscribers one after another: the recorder's
        # last one can still be on its way to the witness when the recorder stops (closed
        # then, the witness once missed the last status under load). Closed once it has it.
        for topic in ("joints", "imu", "status"):
            last = list(back.decoded(topic))[-1].stamp
            with heard:
                assert heard.wait_for(lambda t=topic, s=last: s in seen[t], timeout=WAIT), topic
        for w in witnesses:
            w.close()
    assert stats.dropped == 0 and stats.undecodable == 0

    summary, messages = finished_file(path)
    counts = summary_counts(summary)
    per_channel_times: dict[str, list[int]] = {}
    for channel, message in messages:
        per_channel_times.setdefault(channel.topic, []).append(message.log_time)
    for times in per_channel_times.values():
        assert times == sorted(times)

    prefix = f"/darwin/{robot_system.robot}"
    for topic in ("joints", "imu", "status"):
        stamps = [m.stamp for m in back.decoded(topic)]
        # Everything the witness saw between the first and last recorded message is recorded.
        window = [s for s in seen[topic] if stamps[0] <= s <= stamps[-1]]
        assert stamps == window, topic
        assert counts[f"{prefix}/{topic}/msgpack"] == len(stamps)
        assert counts[f"{prefix}/{topic}"] == len(stamps)
    assert len(back.topic("joints")) > 50

    # Replay into a fresh key space; a Robot client there sees the recorded robot as live.
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    with open_server([endpoint]) as server:
        replayer = Replayer(back, server, "walk-replay", rate=4.0).start(paused=True)
        try:
            with Robot(endpoint, "walk-replay") as viewer:
                got: queue.Queue[Joints] = queue.Queue()
                viewer.subscribe("joints", got.put)
                ReplayControl(viewer).resume()
                imu = viewer.wait_for("imu", timeout=10, fresh=False)  # none before resume
                assert isinstance(imu, Imu)
                replayed = [got.get(timeout=10) for _ in back.topic("joints")]
                assert replayer.wait(timeout=30)
        finally:
            replayer.stop()
    assert [j.tick for j in replayed] == [j.tick for j in back.decoded("joints")]
    assert viewer.state.joints is not None
