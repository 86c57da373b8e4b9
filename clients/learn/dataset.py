"""A LeRobotDataset v3 writer for the policy contract: state and action at the policy rate.

Layout (LeRobot ``CODEBASE_VERSION = "v3.0"``)::

    meta/info.json                                 features, fps, counts, path templates
    meta/stats.json                                min/max/mean/std/count per numeric feature
    meta/tasks.parquet                             task (index) → task_index
    meta/episodes/chunk-000/file-000.parquet       one row per episode: length, tasks, offsets
    data/chunk-000/file-NNN.parquet                the frames of episode NNN

    videos/observation.images.<camera>/chunk-000/file-NNN.mp4   the camera, with ``camera=``

Durable per episode: an episode's frames are written to a file of its own when it ends, then the
metadata files are replaced atomically (write, fsync, rename); a kill loses at most the open
episode. ``observation.state`` is the 69-number observation vector (schemas/policy.py order),
``action`` the 20 actions; ``takeover`` marks frames a human drove (an e-stop, a teleop). With a
``camera`` name each frame also takes the camera's JPEG; the episode's images are encoded as it
goes (OpenCV's MPEG-4 Part 2, ``mp4v``: the codec every OpenCV build writes; LeRobot decodes it
through FFmpeg) into a file renamed into place when the episode ends.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from schemas.extras import require
from schemas.joints import JOINT_NAMES
from schemas.policy import OBSERVATION_LAYOUT, OBSERVATION_SIZE

CODEBASE_VERSION = "v3.0"
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
EPISODES_PATH = "meta/episodes/chunk-000/file-000.parquet"
VIDEO_CODEC = "mp4v"


def _state_names() -> list[str]:
    names = []
    for field, n in OBSERVATION_LAYOUT:
        parts = JOINT_NAMES if n == len(JOINT_NAMES) else ("x", "y", "z")[:n]
        names += [f"{field}.{p}" for p in parts]
    return names


FEATURES: dict[str, dict[str, Any]] = {
    "observation.state": {"dtype": "float32", "shape": [OBSERVATION_SIZE], "names": _state_names()},
    "action": {"dtype": "float32", "shape": [len(JOINT_NAMES)], "names": list(JOINT_NAMES)},
    "takeover": {"dtype": "bool", "shape": [1], "names": None},
    "timestamp": {"dtype": "float32", "shape": [1], "names": None},
    "frame_index": {"dtype": "int64", "shape": [1], "names": None},
    "episode_index": {"dtype": "int64", "shape": [1], "names": None},
    "index": {"dtype": "int64", "shape": [1], "names": None},
    "task_index": {"dtype": "int64", "shape": [1], "names": None},
}


def _atomic(path: Path, write: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    write(tmp)
    with open(tmp, "rb+") as f:
        os.fsync(f.fileno())
    os.replace(tmp, path)


def image_key(camera: str) -> str:
    return f"observation.images.{camera}"


def video_feature(height: int, width: int, fps: float) -> dict[str, Any]:
    return {
        "dtype": "video",
        "shape": [height, width, 3],
        "names": ["height", "width", "channels"],
        "info": {
            "video.height": height, "video.width": width, "video.codec": VIDEO_CODEC,
            "video.pix_fmt": "yuv420p", "video.is_depth_map": False, "video.fps": fps,
            "video.channels": 3, "has_audio": False,
        },
    }  # fmt: skip


class _Video:
    """One episode's camera images, encoded as they come into a file beside its final name."""

    def __init__(self, path: Path, fps: float, first: bytes) -> None:
        self.cv2 = require("cv2", "the dataset's camera video")
        image = self._decode(first)
        self.height, self.width = image.shape[:2]
        self.path = path
        self.tmp = path.with_name(path.name + ".tmp.mp4")
        path.parent.mkdir(parents=True, exist_ok=True)
        fourcc = self.cv2.VideoWriter_fourcc(*VIDEO_CODEC)
        self.out = self.cv2.VideoWriter(str(self.tmp), fourcc, fps, (self.width, self.height))
        if not self.out.isOpened():
            raise OSError(f"OpenCV cannot write {VIDEO_CODEC} video to {self.tmp}")
        self.frames = 0
        self.last = image

    def _decode(self, jpeg: bytes) -> Any:
        image = self.cv2.imdecode(np.frombuffer(jpeg, np.uint8), self.cv2.IMREAD_COLOR)
        if image is None:
            raise ValueError("a camera image is not a JPEG OpenCV can decode")
        return image

    def add(self, jpeg: bytes | None) -> None:
        """The frame's image (None, or one that does not decode: the one before again)."""
        if jpeg is not None:
            try:
                image = self._decode(jpeg)
            except ValueError:
                image = self.last
            if image.shape[:2] != (self.height, self.width):
                image = self.cv2.resize(image, (self.width, self.height))
            self.last = image
        self.out.write(self.last)
        self.frames += 1

    def close(self) -> None:
        self.out.release()
        with open(self.tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(self.tmp, self.path)

    def discard(self) -> None:
        self.out.release()
        self.tmp.unlink(missing_ok=True)


class LeRobotWriter:
    def __init__(
        self,
        root: str | Path,
        fps: float,
        robot_type: str = "darwin_op",
        camera: str | None = None,
    ) -> None:
        self.root = Path(root)
        self.fps = fps
        self.robot_type = robot_type
        self.camera = camera  # name of the camera whose images each frame carries
        self.features: dict[str, dict[str, Any]] = dict(FEATURES)
        self._video: _Video | None = None
        self.episodes: list[dict[str, Any]] = []
        self.tasks: dict[str, int] = {}
        self.total = 0
        self._frames: list[dict[str, Any]] = []
        self._task = ""
        self._all_state: list[np.ndarray] = []
        self._all_action: list[np.ndarray] = []
        if (self.root / "meta" / "info.json").exists():
            raise FileExistsError(f"{self.root} already holds a dataset: choose another directory")

    def add_frame(
        self,
        state: Any,
        action: Any,
        task: str,
        takeover: bool = False,
        image: bytes | None = None,
    ) -> None:
        """One frame; ``image`` is the camera's JPEG (with ``camera``: the first frame of an
        episode needs one, later ones without repeat the image before)."""
        s = np.asarray(state, np.float32).reshape(-1)
        a = np.asarray(action, np.float32).reshape(-1)
        if s.shape != (OBSERVATION_SIZE,) or a.shape != (len(JOINT_NAMES),):
            raise ValueError(f"state must be {OBSERVATION_SIZE} numbers and action 20")
        if self._frames and task != self._task:
            raise ValueError("one task per episode: end the episode before changing it")
        if self.camera is not None:
            self._add_image(image)
        self._task = task
        self._frames.append({"state": s, "action": a, "takeover": bool(takeover)})

    @property
    def open_frames(self) -> int:
        """Frames of the episode not yet written."""
        return len(self._frames)

    def _add_image(self, image: bytes | None) -> None:
        if self._video is None:
            if image is None:
                raise ValueError(f"the first frame of an episode needs a {self.camera} image")
            ep = len(self.episodes)
            key = image_key(str(self.camera))
            path = self.root / VIDEO_PATH.format(video_key=key, chunk_index=0, file_index=ep)
            video = _Video(path, self.fps, image)
            shape = [video.height, video.width, 3]
            if key in self.features and self.features[key]["shape"] != shape:
                video.discard()
                raise ValueError(f"the {self.camera} images changed size to {shape[:2]}")
            self.features[key] = video_feature(video.height, video.width, self.fps)
            self._video = video
        self._video.add(image)

    def end_episode(self) -> int:
        """Write the open episode; returns its index (-1 when it had no frames)."""
        if not self._frames:
            return -1
        ep = len(self.episodes)
        n = len(self._frames)
        task_index = self.tasks.setdefault(self._task, len(self.tasks))
        table = pa.table({
            "observation.state": pa.array([f["state"] for f in self._frames],
                                          pa.list_(pa.float32(), OBSERVATION_SIZE)),
            "action": pa.array([f["action"] for f in self._frames],
                               pa.list_(pa.float32(), len(JOINT_NAMES))),
            "takeover": pa.array([f["takeover"] for f in self._frames], pa.bool_()),
            "timestamp": pa.array(np.arange(n, dtype=np.float32) / np.float32(self.fps)),
            "frame_index": pa.array(np.arange(n, dtype=np.int64)),
            "episode_index": pa.array(np.full(n, ep, np.int64)),
            "index": pa.array(np.arange(self.total, self.total + n, dtype=np.int64)),
            "task_index": pa.array(np.full(n, task_index, np.int64)),
        })  # fmt: skip
        path = self.root / DATA_PATH.format(chunk_index=0, file_index=ep)
        _atomic(path, lambda p: pq.write_table(table, p))
        videos: dict[str, Any] = {}
        if self._video is not None:
            self._video.close()
            self._video = None
            key = f"videos/{image_key(str(self.camera))}"
            videos = {f"{key}/chunk_index": 0, f"{key}/file_index": ep,
                      f"{key}/from_timestamp": 0.0, f"{key}/to_timestamp": n / self.fps}
        self.episodes.append({
            "episode_index": ep, "tasks": [self._task], "length": n,
            "data/chunk_index": 0, "data/file_index": ep,
            "dataset_from_index": self.total, "dataset_to_index": self.total + n,
            "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0,
            "takeover_frames": sum(f["takeover"] for f in self._frames),
            **videos,
        })  # fmt: skip
        self._all_state += [f["state"] for f in self._frames]
        self._all_action += [f["action"] for f in self._frames]
        self.total += n
        self._frames = []
        self._write_meta()
        return ep

    def _write_meta(self) -> None:
        eps = pa.Table.from_pylist(self.episodes)
        _atomic(self.root / EPISODES_PATH, lambda p: pq.write_table(eps, p))
        tasks = pa.table({"task_index": list(self.tasks.values()), "task": list(self.tasks)})
        _atomic(self.root / "meta/tasks.parquet", lambda p: pq.write_table(tasks, p))
        info = {
            "codebase_version": CODEBASE_VERSION,
            "robot_type": self.robot_type,
            "total_episodes": len(self.episodes),
            "total_frames": self.total,
            "total_tasks": len(self.tasks),
            "chunks_size": 1000,
            "data_files_size_in_mb": 100,
            "video_files_size_in_mb": 500,
            "fps": self.fps,
            "splits": {"train": f"0:{len(self.episodes)}"},
            "data_path": DATA_PATH,
            "video_path": VIDEO_PATH if self.camera is not None else None,
            "features": self.features,
        }
        _atomic(self.root / "meta/info.json", lambda p: p.write_text(json.dumps(info, indent=2)))
        stats = {
            "observation.state": _stats(np.array(self._all_state)),
            "action": _stats(np.array(self._all_action)),
        }
        _atomic(self.root / "meta/stats.json", lambda p: p.write_text(json.dumps(stats)))


def _stats(x: np.ndarray) -> dict[str, Any]:
    return {
        "min": x.min(0).tolist(),
        "max": x.max(0).tolist(),
        "mean": x.mean(0).tolist(),
        "std": x.std(0).tolist(),
        "count": [int(len(x))],
    }
