"""`darwin record --lerobot DIR` against the real stack (`darwin up` with the simulated camera):
frames from the policy observations, the applied action while a policy streams and the reached
positions (flagged takeover) while nobody does, episodes ended by the `episode` op and by a line
on the recorder's standard input, the camera as one mp4 per episode, the last episode written on
SIGTERM; bad options refused in one line."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from clients.learn.stream import PolicyStream
from clients.recording.control import RecordControl
from clients.robot import Robot
from schemas.errors import RobotUnreachableError
from schemas.policy import DEFAULT_SCALE, OBSERVATION_LAYOUT
from tests.fixtures.emulator import darwin_command
from tests.fixtures.policy_stream import settle
from tests.fixtures.system import REPO, RunningSystem, start_system

pytest.importorskip("pyarrow", reason="pip install -e '.[learn]' runs this test")
cv2 = pytest.importorskip("cv2", reason="pip install -e '.[vision]' runs this test")

WAIT = 30.0
JOINT_POS = sum(n for name, n in OBSERVATION_LAYOUT[:3])  # gyro, gravity, command come first


@pytest.fixture(scope="module")
def system() -> Iterator[RunningSystem]:
    with start_system(camera="sim", gateway=False) as running:
        yield running


def until(condition: Callable[[], object], what: str, process: subprocess.Popen[str]) -> None:
    """Ask again until ``condition()`` holds (the recorder answers its status on request)."""
    deadline = time.monotonic() + WAIT
    while not condition():
        assert process.poll() is None, f"the recorder exited: {process.stderr}"
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")


def frames_in_open_episode(control: RecordControl, at_least: int) -> Callable[[], bool]:
    def check() -> bool:
        try:
            return control.status()["open_frames"] >= at_least
        except RobotUnreachableError:  # the queryable is not declared yet
            return False

    return check


def test_a_live_recording_is_a_lerobot_dataset_with_episodes_video_and_takeover(
    system: RunningSystem, tmp_path: Path
) -> None:
    root = tmp_path / "dataset"
    recorder = subprocess.Popen(
        darwin_command("record", "--lerobot", str(root), "--task", "stand still",
                       "--connect", system.endpoint, "--robot", system.robot),
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO,
    )  # fmt: skip
    assert recorder.stdin is not None and recorder.stderr is not None
    try:
        line = recorder.stderr.readline()
        assert line.startswith("recording ") and "LeRobotDataset v3" in line, line
        with system.robot_client(name="lerobot-test") as robot:
            control = RecordControl(robot)
            until(frames_in_open_episode(control, 20), "frames while nobody drives", recorder)
            _stream_zero_actions(robot, 60)
            until(frames_in_open_episode(control, 80), "the policy frames", recorder)
            ended = control.episode(task="second")
            assert ended["ended"] == 0 and ended["task"] == "second"
            until(frames_in_open_episode(control, 10), "frames of episode 1", recorder)
            recorder.stdin.write("third\n")  # Enter (with a task) on the recorder's terminal
            recorder.stdin.flush()
            until(lambda: control.status()["episodes"] == 2, "episode 1 ended by a key", recorder)
            until(frames_in_open_episode(control, 10), "frames of episode 2", recorder)
        recorder.send_signal(signal.SIGTERM)
        _, err = recorder.communicate(timeout=WAIT)
    finally:
        if recorder.poll() is None:
            recorder.kill()
            recorder.wait()
    assert recorder.returncode == 0, err
    assert "Traceback" not in err
    assert "wrote 3 episode(s)" in err, err

    info = json.loads((root / "meta/info.json").read_text())
    assert info["total_episodes"] == 3 and info["fps"] == 50.0
    video = info["features"]["observation.images.head_camera"]
    assert video["dtype"] == "video" and video["info"]["video.codec"] == "mp4v"
    episodes = pd.read_parquet(root / "meta/episodes/chunk-000/file-000.parquet")
    assert list(episodes["tasks"].map(list)) == [["stand still"], ["second"], ["third"]]
    tasks = pd.read_parquet(root / "meta/tasks.parquet")
    assert set(tasks["task"]) == {"stand still", "second", "third"}

    first = pd.read_parquet(root / "data/chunk-000/file-000.parquet")
    assert len(first) == episodes["length"][0]
    assert list(first["frame_index"]) == list(range(len(first)))
    state = np.stack(first["observation.state"].to_numpy())
    action = np.stack(first["action"].to_numpy())
    takeover = first["takeover"].to_numpy()
    policy = ~takeover
    assert takeover.any() and policy.any()  # nobody drove, then the policy did
    # Policy frames: what the daemon applied for a zero offset (the default pose), in offset
    # units: it reaches 0 once the per-step cap has let the joints get there.
    # (Some of the last frames, not every one: a test process starved past a deadline gets
    # the daemon's hold for that frame, which a loaded CI run recorded as 0.09.)
    assert (np.abs(action[policy][-10:]).max(axis=1) < 1e-3).any()
    # Takeover frames: where the joints went (the next observation's positions), offset units.
    reached = state[:, JOINT_POS : JOINT_POS + 20] / DEFAULT_SCALE
    before = np.flatnonzero(takeover[:-1] & takeover[1:])
    assert np.abs(action[before] - reached[before + 1]).max() < math.radians(0.5) / DEFAULT_SCALE

    for ep, length in enumerate(episodes["length"]):
        path = root / f"videos/observation.images.head_camera/chunk-000/file-{ep:03d}.mp4"
        capture = cv2.VideoCapture(str(path))
        try:
            assert capture.isOpened(), path
            assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == length
            ok, image = capture.read()
            assert ok and list(image.shape) == video["shape"]
        finally:
            capture.release()
        assert episodes["videos/observation.images.head_camera/to_timestamp"][ep] == (
            pytest.approx(length / 50.0)
        )
    assert not list(root.rglob("*.tmp*"))


def _stream_zero_actions(robot: Robot, steps: int) -> None:
    with robot.control():
        stream = PolicyStream(robot).start(rate_hz=50)
        try:
            last = -1
            for _ in range(steps):
                obs = stream.next_observation(last, timeout=WAIT)
                assert obs is not None
                last = obs.tick
                stream.send([0.0] * 20, obs.tick)
            settle(stream, [0.0] * 20)  # the last answered (an action or answer may be lost)
        finally:
            stream.stop()
            stream.close()


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--lerobot", "{tmp}/d", "-o", "{tmp}/x.mcap"], "not both"),
        (["--lerobot", "{tmp}/d", "--fps", "500"], "--fps 500.0 must be within 1..125"),
        (["--lerobot", "{tmp}/d", "--robot", "a", "--robot", "b"], "records one robot"),
        (["--lerobot", "{tmp}/taken"], "already holds a dataset"),
    ],
)
def test_bad_lerobot_options_are_refused_in_one_line(
    args: list[str], says: str, tmp_path: Path
) -> None:
    (tmp_path / "taken/meta").mkdir(parents=True)
    (tmp_path / "taken/meta/info.json").write_text("{}")
    out = subprocess.run(
        darwin_command("record", *(a.format(tmp=tmp_path) for a in args)),
        capture_output=True, text=True, timeout=60, cwd=REPO,
    )  # fmt: skip
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 2 and len(lines) == 1, out.stderr
    assert lines[0].startswith("darwin record: ") and says in lines[0], lines
