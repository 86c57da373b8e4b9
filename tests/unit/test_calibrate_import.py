"""`darwin calibrate import`: ROBOTIS's [Offset] section into the user config, through the one
user-config writer, which keeps everything else in the file."""

from __future__ import annotations

import subprocess
import tomllib
from pathlib import Path

import pytest

from config.loader import load_robot
from config.robotis_offsets import import_offsets, read_offset_steps
from config.user_file import set_joint_offsets
from schemas.errors import ConfigError
from tests.fixtures.system import REPO, darwin_command

# As ROBOTIS's framework writes it (minIni): other sections around, two-digit IDs.
SAMPLE_INI = """\
[Walking Config]
x_offset = -10
pelvis_offset = 3.0

[Offset]
ID_01 = 0
ID_02 = 8
ID_13 = -12
ID_14 = 16 ; nudged after a fall
ID_20 = -4

[Team]
number = 1
"""

USER_FILE = """\
# my robot
[daemon]
tick_ms = 8.0  # the loop

[robot.joints.r_knee]
max_deg = 120.0 # keep
offset_deg = 0.5

[gateway]
max_rate = 50
"""


def test_steps_are_read_from_the_offset_section_only() -> None:
    assert read_offset_steps(SAMPLE_INI) == {1: 0, 2: 8, 13: -12, 14: 16, 20: -4}


def test_steps_become_degrees_with_their_sign(tmp_path: Path) -> None:
    ini = tmp_path / "config.ini"
    ini.write_text(SAMPLE_INI)
    got = import_offsets(ini, load_robot())
    assert got.degrees["r_knee"] == pytest.approx(-12 * 360 / 4096)  # ID 13
    assert got.degrees["l_knee"] == pytest.approx(16 * 360 / 4096)  # ID 14
    assert got.degrees["head_tilt"] == pytest.approx(-4 * 360 / 4096)  # ID 20
    assert got.ignored == []


def test_the_command_writes_offsets_and_keeps_the_rest(tmp_path: Path) -> None:
    ini = tmp_path / "config.ini"
    ini.write_text(SAMPLE_INI)
    user = tmp_path / "config.toml"
    user.write_text(USER_FILE)
    out = subprocess.run(
        darwin_command("calibrate", "import", str(ini), "--config", str(user)),
        capture_output=True,
        text=True,
        timeout=60,
        cwd=REPO,
    )
    assert out.returncode == 0, out.stderr
    assert f"config: {user}" in out.stdout
    text = user.read_text()
    assert "# my robot" in text and "tick_ms = 8.0  # the loop" in text
    assert "max_deg = 120.0 # keep" in text
    data = tomllib.loads(text)
    assert data["gateway"] == {"max_rate": 50}
    robot = load_robot(user)
    assert robot.joint("r_knee").offset_deg == pytest.approx(-12 * 360 / 4096)
    assert robot.joint("r_knee").max_deg == 120.0
    assert robot.joint("l_shoulder_pitch").offset_deg == pytest.approx(8 * 360 / 4096)
    assert robot.joint("r_shoulder_pitch").offset_deg == 0.0
    assert robot.joint("r_hip_yaw").offset_deg == 0.0  # not in the file: untouched


def test_a_second_import_replaces_the_values_in_place(tmp_path: Path) -> None:
    user = tmp_path / "config.toml"
    set_joint_offsets({"r_knee": 1.0, "l_knee": 2.0}, user)
    first = user.read_text()
    set_joint_offsets({"r_knee": -1.0, "l_knee": 2.0}, user)
    second = user.read_text()
    assert second.count("[robot.joints.r_knee]") == 1
    assert second.count("offset_deg") == 2
    assert len(second.splitlines()) == len(first.splitlines())
    assert load_robot(user).joint("r_knee").offset_deg == -1.0


@pytest.mark.parametrize(
    ("ini", "words"),
    [
        ("[Walking Config]\nx_offset = 1\n", "has no [Offset] section"),
        ("[Offset]\nID_01 = 3.5\n", "is not a whole number"),
        ("[Offset]\nID_01 = 900\n", "beyond ±512"),
        ("[Offset]\nSPEED = 1\n", "is not ID_nn"),
    ],
)
def test_a_wrong_file_is_refused_in_one_line(ini: str, words: str, tmp_path: Path) -> None:
    path = tmp_path / "config.ini"
    path.write_text(ini)
    user = tmp_path / "config.toml"
    out = subprocess.run(
        darwin_command("calibrate", "import", str(path), "--config", str(user)),
        capture_output=True,
        text=True,
        timeout=60,
        cwd=REPO,
    )
    assert out.returncode == 1
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("darwin calibrate:") and words in lines[0]
    assert not user.exists()


def test_a_file_the_writer_cannot_edit_safely_is_left_alone(tmp_path: Path) -> None:
    user = tmp_path / "config.toml"
    text = "[robot]\njoints = { r_knee = { offset_deg = 1.0 } }\n"
    user.write_text(text)
    with pytest.raises(ConfigError, match="by hand"):
        set_joint_offsets({"r_knee": 2.0}, user)
    assert user.read_text() == text


def test_without_config_the_import_lands_in_the_robots_file_the_daemon_reads(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """On the robot the recipe writes /etc/darwin/config.toml and the daemon reads it: an import
    without --config (no user file, no $DARWIN_CONFIG) writes there, and the loader reads it."""
    import config.loader as loader
    from config.user_file import target_path

    system = tmp_path / "etc" / "config.toml"
    system.parent.mkdir()
    system.write_text(USER_FILE)
    monkeypatch.setattr(loader, "SYSTEM_CONFIG", system)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "home"))
    monkeypatch.delenv("DARWIN_CONFIG", raising=False)
    assert target_path() == system
    ini = tmp_path / "config.ini"
    ini.write_text(SAMPLE_INI)
    assert set_joint_offsets(import_offsets(str(ini), load_robot(system)).degrees) == system
    assert loader.load_all()["robot"]["joints"]["r_knee"]["offset_deg"] == pytest.approx(
        -12 * 360 / 4096
    )
    # A user file, once there, comes first for both.
    user = tmp_path / "home" / "darwin" / "config.toml"
    user.parent.mkdir(parents=True)
    user.write_text("[daemon]\ntick_ms = 8.0\n")
    assert target_path() == user
