"""The notebook side of the Robot client against a real Zenoh peer publishing the robot's
message types: stream() → DataFrame, image() → numpy, state arrays, live views."""

from __future__ import annotations

import ast
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from clients.dataframes import joint_columns
from clients.notebook import NOTEBOOKS, example_notebooks
from clients.robot import Robot
from config.loader import load_robot
from schemas.errors import CommandTimeoutError
from schemas.messages import CameraFrame, encode
from tests.fixtures.emulator import wait_until
from tests.fixtures.system import RunningSystem, start_system
from tests.integration.test_recording_mcap import ROBOT, Source, imu_msg, joints_msg


class Publishing:
    """A Source that keeps publishing joints/IMU every 8 ms (and camera frames if asked)."""

    def __init__(self, camera: bool = False) -> None:
        self.src = Source()
        self.stop = threading.Event()
        self.camera = camera
        ok, jpeg = cv2.imencode(".jpg", np.full((24, 32, 3), (0, 0, 255), np.uint8))  # BGR red
        assert ok
        self.jpeg = jpeg.tobytes()
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self) -> None:
        tick = 0
        while not self.stop.wait(0.008):
            self.src.pubs["joints"].put(encode(joints_msg(tick)))
            self.src.pubs["imu"].put(encode(imu_msg(tick)))
            if self.camera and tick % 4 == 0:
                frame = CameraFrame(jpeg=self.jpeg, width=32, height=24, seq=tick)
                self.src.pubs["camera"].put(encode(frame))
            tick += 1

    def close(self) -> None:
        self.stop.set()
        self.thread.join()
        self.src.close()


@pytest.fixture
def publishing() -> Iterator[Publishing]:
    p = Publishing(camera=True)
    yield p
    p.close()


@pytest.fixture
def robot(publishing: Publishing) -> Iterator[Robot]:
    with Robot(publishing.src.endpoint, ROBOT, name="nb-test") as r:
        # The state holds what has arrived: wait for both streams the tests read from it.
        r.wait_for("joints", timeout=10)
        r.wait_for("imu", timeout=10)
        yield r


def test_stream_gives_one_row_per_tick_and_a_column_per_joint_field(robot: Robot) -> None:
    df = robot.stream("joints", seconds=5, max_messages=25)
    names = load_robot().names
    assert len(df) == 25 and df.index.name == "t"
    assert df.index[0] == 0.0 and df.index.is_monotonic_increasing
    assert {f"position_{n}" for n in names} <= set(df.columns)
    assert {f"load_{n}" for n in names} <= set(df.columns)
    assert list(np.diff(df["tick"])) == [1] * 24
    pos = joint_columns(df)
    assert list(pos.columns) == list(names)
    assert pos[names[1]].iloc[0] == pytest.approx(0.01 * df["tick"].iloc[0] + 0.1)


def test_stream_imu_columns(robot: Robot) -> None:
    df = robot.stream("imu", seconds=5, max_messages=5)
    for col in ("gyro_x", "gyro_y", "gyro_z", "accel_z", "accel_raw_z", "fall", "tick"):
        assert col in df.columns
    assert (df["accel_z"] == 9.81).all()


def test_image_is_rgb_and_camera_is_unsubscribed_after(
    robot: Robot, publishing: Publishing
) -> None:
    img = robot.image(timeout=10)
    assert img.shape == (24, 32, 3) and img.dtype == np.uint8
    r, g, b = img[12, 16]
    assert r > 200 and g < 60 and b < 60  # red stays red: channels are RGB
    cam = publishing.src.pubs["camera"]
    wait_until(lambda: not cam.matching_status.matching, what="camera unsubscribed")


def test_image_without_camera_says_what_to_check() -> None:
    p = Publishing(camera=False)
    try:
        with (
            Robot(p.src.endpoint, ROBOT) as r,
            pytest.raises(CommandTimeoutError, match="camera on"),
        ):
            r.image(timeout=0.3)
    finally:
        p.close()


def test_state_arrays_and_repr(robot: Robot) -> None:
    st = robot.state
    assert st.array("position").shape == (20,)
    np.testing.assert_allclose(st.array("accel"), [0.0, 0.1, 9.81])
    with pytest.raises(ValueError, match="joint columns"):
        st.array("elbow")
    assert repr(robot) == f"<Robot {ROBOT} at {robot.target.endpoint}: 20 joints, lease: none>"


def test_live_plot_and_camera_render_without_blocking(robot: Robot) -> None:
    # The notebook's widgets (ipywidgets, matplotlib) and the kernel's client (nbformat,
    # nbclient) are imported by the tests that use them: at the module's top they cost every
    # pytest-xdist worker ~0.8 s of CPU at collection, and one worker runs this file.
    from clients.notebook.live import LiveCamera, LivePlot

    with LivePlot(robot, ["imu.gyro_x", "joints.position_r_knee"], interval=0.05) as plot:
        assert plot.wait(frames=2)
        assert bytes(plot.widget.value).startswith(b"\x89PNG")
        data = plot.data()
        assert data["imu.gyro_x"] and data["joints.position_r_knee"]
        bundle = plot._repr_mimebundle_()
        assert "application/vnd.jupyter.widget-view+json" in bundle
    with LiveCamera(robot, interval=0.05) as cam:
        assert cam.wait(frames=1)
        assert bytes(cam.widget.value).startswith(b"\xff\xd8")


@pytest.mark.parametrize("bad", ["gyro_x", "elbow.x", "imu."])
def test_bad_signal_names_are_explained(bad: str) -> None:
    from clients.notebook.live import parse_signal

    with pytest.raises(ValueError, match=r"<topic>\.<column>"):
        parse_signal(bad)


# -- the example notebooks, executed by a real kernel against the simulator -------------------


@pytest.fixture
def sim_system() -> Iterator[RunningSystem]:
    """A `darwin up` of its own per notebook, with the simulated camera: each notebook drives
    the robot and must start from the simulator's initial scene (the ball in view)."""
    with start_system(camera="sim", gateway=False) as system:
        yield system


def run_notebook(name: str, system: RunningSystem, tmp_path: Path, monkeypatch) -> Any:
    import nbformat
    from nbclient import NotebookClient

    book = nbformat.read(NOTEBOOKS / name, as_version=4)
    monkeypatch.setenv("DARWIN_ENDPOINT", system.endpoint)
    monkeypatch.setenv("DARWIN_ROBOT", system.robot)
    # kernel "python3" from the venv: jupyter_client runs its `python` as sys.executable.
    client = NotebookClient(
        book, kernel_name="python3", timeout=60, resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()
    return book


def outputs(book: Any, mime: str) -> list[Any]:
    return [
        out["data"][mime]
        for cell in book.cells
        if cell.cell_type == "code"
        for out in cell.get("outputs", [])
        if mime in out.get("data", {})
    ]


def printed(book: Any) -> str:
    return "".join(
        out.get("text", "")
        for cell in book.cells
        if cell.cell_type == "code"
        for out in cell.get("outputs", [])
        if out.get("output_type") == "stream"
    )


def shapes(book: Any) -> list[tuple[int, int]]:
    """Every `df.shape` a cell displayed, in order (also inside displayed tuples)."""
    found = []
    for text in outputs(book, "text/plain"):
        try:
            value = ast.literal_eval(text)
        except (ValueError, SyntaxError):
            continue
        items = (
            value if isinstance(value, tuple) and value and isinstance(value[0], tuple) else [value]
        )
        found += [v for v in items if isinstance(v, tuple) and all(type(x) is int for x in v)]
    return found


def test_every_example_notebook_is_tested() -> None:
    assert {p.name for p in example_notebooks()} == set(NOTEBOOK_CHECKS)


def check_imu_walk(book: Any) -> None:
    (rows, cols), *_ = shapes(book)
    assert rows > 10 and cols >= 15
    tables = outputs(book, "text/html")
    assert any("gyro_x" in t and "accel_z" in t and "mean" in t for t in tables)
    assert len(outputs(book, "image/png")) >= 1  # the matplotlib figure
    assert any(t.startswith("(True, <LivePlot imu.gyro_x") for t in outputs(book, "text/plain"))
    assert outputs(book, "application/vnd.jupyter.widget-view+json")


def check_ball_finder(book: Any) -> None:
    image_shape, frames_shape = shapes(book)[:2]
    assert image_shape == (240, 320, 3) and frames_shape == (5, 3)
    table = next(t for t in outputs(book, "text/html") if "pan_error" in t)
    assert table.count("True") == 5  # the simulated ball is in view in every frame
    assert "True <LiveCamera" in printed(book)
    assert len(outputs(book, "image/png")) == 1


def check_action_trajectories(book: Any) -> None:
    (steps, driven), (rows, cols) = shapes(book)[:2]
    assert steps >= 1 and driven >= 1 and cols == driven and rows > 20
    match = next(t for t in outputs(book, "text/plain") if "rms_error_deg" in t)
    last = match.strip().splitlines()[-1].split()
    assert int(last[0]) == steps
    assert float(last[-1]) < 5.0  # the robot ends on the page's last key frame
    assert len(outputs(book, "image/png")) == 1


def check_choreography(book: Any) -> None:
    texts = outputs(book, "text/plain")
    assert "7" in texts  # len(dance)
    summary = next(t for t in texts if "choreography.mcap" in t)
    assert "joints" in summary and "dropped" not in summary
    events = next(t for t in outputs(book, "text/html") if "item_started" in t)
    assert "started" in events and "finished" in events and events.count("item_finished") == 7
    (rows, cols), *_ = shapes(book)
    assert cols == 2 and rows > 20
    assert len(outputs(book, "image/png")) == 1


NOTEBOOK_CHECKS = {
    "choreography.ipynb": check_choreography,
    "action_trajectories.ipynb": check_action_trajectories,
    "imu_walk.ipynb": check_imu_walk,
    "ball_finder.ipynb": check_ball_finder,
}


@pytest.mark.parametrize("name", sorted(NOTEBOOK_CHECKS))
def test_example_notebook_runs_top_to_bottom(
    name: str, sim_system: RunningSystem, tmp_path: Path, monkeypatch
) -> None:
    heard: list[Any] = []
    with (
        sim_system.robot_client(name="events witness") as witness,
        witness.subscribe("events", heard.append),
    ):
        book = run_notebook(name, sim_system, tmp_path, monkeypatch)
    try:
        NOTEBOOK_CHECKS[name](book)
    except AssertionError as failed:
        # What the daemon said meanwhile (a servo offline, a protective stop, a lease that
        # ended): the book shows only what its cells chose to. (A choreography "stopped:
        # halted" once beside busy loops, and the book could not say why.)
        said = "\n".join(f"{e.kind}: {e.message}" for e in heard)
        raise AssertionError(f"{failed}\nthe daemon's events:\n{said}") from None
