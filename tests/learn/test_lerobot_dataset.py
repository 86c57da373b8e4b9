"""LeRobotDataset v3 written from episodes of the fast backend, read back with pyarrow/pandas
against the v3 layout, and (when LeRobot is installed) by LeRobotDataset itself."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

import clients.learn.env  # noqa: F401
from clients.learn.dataset import LeRobotWriter
from clients.learn.examples.stand_balance import StandBalance
from clients.learn.fast import Randomization


def _record(root: Path, episodes: int = 2, steps: int = 30) -> LeRobotWriter:
    env = gym.make("darwin/Stand-v0", randomize=Randomization.off())
    writer = LeRobotWriter(root, fps=50)
    for ep in range(episodes):
        policy = StandBalance()
        obs, _ = env.reset(seed=ep)
        for k in range(steps):
            action = policy(obs)
            writer.add_frame(obs, action, "stand", takeover=(ep == 1 and k >= 20))
            obs, *_ = env.step(action)
        writer.end_episode()
    env.close()
    return writer


def test_the_dataset_reads_back_in_the_v3_layout(tmp_path: Path) -> None:
    root = tmp_path / "stand"
    _record(root)
    info = json.loads((root / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["fps"] == 50
    assert info["total_episodes"] == 2 and info["total_frames"] == 60
    assert info["features"]["observation.state"]["shape"] == [69]
    assert info["features"]["action"]["names"][12] == "r_knee"
    frames = pd.concat(
        pd.read_parquet(root / info["data_path"].format(chunk_index=0, file_index=i))
        for i in range(2)
    )
    assert list(frames["index"]) == list(range(60))
    assert frames["episode_index"].tolist() == [0] * 30 + [1] * 30
    assert np.stack(frames["action"]).shape == (60, 20)
    assert frames["takeover"].sum() == 10
    assert frames["timestamp"].iloc[29] == pytest.approx(29 / 50)
    episodes = pq.read_table(root / "meta/episodes/chunk-000/file-000.parquet").to_pandas()
    assert episodes["length"].tolist() == [30, 30]
    assert episodes["dataset_to_index"].tolist() == [30, 60]
    assert list(episodes["tasks"].iloc[0]) == ["stand"]
    tasks = pd.read_parquet(root / "meta/tasks.parquet")
    assert tasks.set_index("task")["task_index"].to_dict() == {"stand": 0}
    stats = json.loads((root / "meta/stats.json").read_text())
    assert len(stats["action"]["mean"]) == 20 and stats["action"]["count"] == [60]


def test_an_episode_is_durable_before_the_next_one_ends(tmp_path: Path) -> None:
    root = tmp_path / "d"
    writer = _record(root, episodes=1, steps=5)
    writer.add_frame(np.zeros(69), np.zeros(20), "stand")  # an open episode, then a "kill"
    info = json.loads((root / "meta/info.json").read_text())
    assert info["total_episodes"] == 1 and info["total_frames"] == 5
    assert not list(root.rglob("*.tmp"))
    with pytest.raises(FileExistsError, match="already holds a dataset"):
        LeRobotWriter(root, fps=50)


def _jpeg(value: int, size: tuple[int, int] = (48, 64)) -> bytes:
    cv2 = pytest.importorskip("cv2")
    ok, data = cv2.imencode(".jpg", np.full((*size, 3), value, np.uint8))
    assert ok
    return data.tobytes()


def test_camera_images_become_one_video_per_episode_of_its_length(tmp_path: Path) -> None:
    cv2 = pytest.importorskip("cv2")
    root = tmp_path / "cam"
    writer = LeRobotWriter(root, fps=25, camera="head_camera")
    with pytest.raises(ValueError, match="needs a head_camera image"):
        writer.add_frame(np.zeros(69), np.zeros(20), "look")
    for length in (12, 7):
        for k in range(length):
            # Frames without a new image, and a broken one, repeat the image before.
            image = _jpeg(40 * (k % 3)) if k % 4 == 0 else (b"not a jpeg" if k == 5 else None)
            writer.add_frame(np.zeros(69), np.zeros(20), "look", image=image)
        writer.end_episode()
    info = json.loads((root / "meta/info.json").read_text())
    feature = info["features"]["observation.images.head_camera"]
    assert feature["dtype"] == "video" and feature["shape"] == [48, 64, 3]
    episodes = pd.read_parquet(root / "meta/episodes/chunk-000/file-000.parquet")
    for ep, length in enumerate((12, 7)):
        path = root / info["video_path"].format(
            video_key="observation.images.head_camera", chunk_index=0, file_index=ep
        )
        capture = cv2.VideoCapture(str(path))
        assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == length
        capture.release()
        key = "videos/observation.images.head_camera"
        assert episodes[f"{key}/file_index"][ep] == ep
        assert episodes[f"{key}/to_timestamp"][ep] == pytest.approx(length / 25)
    # Another size in a later episode is refused, and nothing of it is left behind.
    with pytest.raises(ValueError, match="changed size"):
        writer.add_frame(np.zeros(69), np.zeros(20), "look", image=_jpeg(0, (32, 32)))
    assert not list(root.rglob("*.tmp*"))


@pytest.mark.skipif(
    importlib.util.find_spec("lerobot") is None,
    reason="lerobot is not installed (it pulls torch; not a dependency of this project)",
)
def test_lerobot_itself_loads_it(tmp_path: Path) -> None:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    root = tmp_path / "stand"
    _record(root)
    ds = LeRobotDataset("local/stand", root=root)
    assert ds.num_episodes == 2 and len(ds) == 60
