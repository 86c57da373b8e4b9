"""The documentation's pictures are drawn from what they show (scripts/pictures.py): the servo
chains from the robot config and the cable order, the Foxglove layout from its file, the
calibration posture from the MuJoCo model. These tests keep the committed pictures in step and
check that each shows what its page says."""

from __future__ import annotations

import html
import importlib.util
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def pictures() -> ModuleType:
    spec = importlib.util.spec_from_file_location("pictures", REPO / "scripts" / "pictures.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    sys.modules["pictures"] = module  # its dataclass looks its module up there
    spec.loader.exec_module(module)
    return module


def _texts(svg: str) -> list[str]:
    return [html.unescape(t).strip() for t in re.findall(r"<text[^>]*>([^<]*)</text>", svg)]


def test_the_script_check_passes() -> None:
    """`python scripts/pictures.py --check`, as the pages show it: every picture in step,
    the MuJoCo one redrawn offscreen and compared."""
    run = subprocess.run([sys.executable, "scripts/pictures.py", "--check"], cwd=REPO,
                         capture_output=True, text=True, env={**os.environ, "CI": "1"})
    assert run.returncode == 0, run.stderr


def test_an_svg_out_of_step_is_named(pictures: ModuleType, tmp_path: Path,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    stale = tmp_path / "servo-chains.svg"
    stale.write_text(pictures.chains_svg().replace(">13<", ">31<"))
    monkeypatch.setattr(pictures, "SVGS", {stale: pictures.chains_svg})
    monkeypatch.setattr(pictures, "REPO", tmp_path)
    assert pictures.main(["--check", "--no-png"]) == 1


def test_the_chains_show_every_servo_of_the_config_on_its_branch(pictures: ModuleType) -> None:
    from config.loader import robot_from_dict, shipped
    from robot_daemon.bus.chains import CHAINS

    texts = _texts(pictures.CHAINS_SVG.read_text())
    robot = robot_from_dict(shipped()["robot"])
    for joint in robot.joints:
        i = texts.index(str(joint.id))  # the ID, then its joint name
        assert texts[i + 1] == joint.name
    assert set(CHAINS) <= set(texts)
    assert f"ID {robot.cm730_id} · 5 TTL ports" in texts


def test_the_foxglove_drawing_has_every_panel_and_series(pictures: ModuleType) -> None:
    layout = json.loads(pictures.LAYOUT.read_text())
    texts = _texts(pictures.FOXGLOVE_SVG.read_text())
    placed = [panel for panel, *_ in pictures._split(layout["layout"], 0, 0, 100, 100)]
    assert sorted(placed) == sorted(layout["configById"])
    for panel, config in layout["configById"].items():
        if "title" in config:
            assert config["title"] in texts, panel
        for path in config.get("paths", []):
            assert f"— {path['label']}" in texts, (panel, path["label"])


def test_the_png_comparison_sees_a_moved_robot(pictures: ModuleType) -> None:
    """The tolerance absorbs GL drivers' rounding, not a change of posture: the committed
    picture shifted by a few pixels (an arm a little elsewhere) is out of step."""
    image = pictures.read_png(pictures.CALIBRATION_PNG)
    assert pictures.differs(image, image) == 0.0
    assert pictures.differs(image, np.roll(image, 6, axis=1)) > pictures.PNG_TOLERANCE


def test_the_ros2_arrangements_say_what_the_page_and_the_programs_say(
        pictures: ModuleType) -> None:
    """The drawing's commands parse as the programs' own and its settings are the page's."""
    import contextlib
    import io
    import shlex

    from robot_daemon.launch.cli import command_parser

    texts = _texts(pictures.ROS2_SVG.read_text())
    page = (REPO / "docs" / "ros2.md").read_text()
    for line in ("--listen tcp/0.0.0.0:7447", "--config router.toml",
                 "--router tcp/ROS_HOST:7447", "rmw_zenoh_cpp", "listens on tcp/[::]:7447"):
        assert line in texts, line
    for fact in ('mode = "router"', 'mode="client"', '["tcp/ROBOT_IP:7447"]', "rmw_zenohd",
                 "--ros-user", "--ros-password-file", "tcp/[::]:7447"):
        assert fact in page, fact
        assert any(fact in text for text in texts), fact
    for command in ("up --ros2 --listen tcp/0.0.0.0:7447 --config router.toml",
                    "ros2 --router tcp/ROS_HOST:7447 --ros-user U --ros-password-file F"):
        name, *args = shlex.split(command)
        _, parser = command_parser(name)
        with contextlib.redirect_stderr(io.StringIO()):
            parser.parse_args(args)  # SystemExit (a failure here) when an option is gone
