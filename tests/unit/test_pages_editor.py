"""The page editing model shared by the TUI and the Robot client: values, steps, mirror, capture,
undo, joint groups."""

from __future__ import annotations

import pytest

from clients.pages import (
    GROUPS,
    JOINTS,
    EditError,
    PageEditor,
    blank_page,
    joints_of,
    mirror_name,
    quantize,
    step_seconds,
)
from config.loader import load_robot
from robot_daemon.motion.action import textfile
from schemas.units import deg_to_raw


def editor() -> PageEditor:
    page = blank_page(200, "test")
    page["step"] = [
        {"time": 50, "pause": 0, "r_shoulder_pitch": -45.0, "r_elbow": 22.5, "head_pan": 11.25},
        {"time": 60, "pause": 5, "r_shoulder_pitch": 22.5},
    ]
    return PageEditor(page)


def test_joint_names_and_groups_match_the_robot_config() -> None:
    robot = load_robot()
    assert tuple(j.name for j in sorted(robot.joints, key=lambda j: j.id)) == JOINTS
    assert joints_of("right_arm") == ["r_shoulder_pitch", "r_shoulder_roll", "r_elbow"]
    assert joints_of(["head", "r_knee"]) == ["r_knee", "head_pan", "head_tilt"]
    assert len(joints_of("legs")) == 12 and joints_of("all") == list(JOINTS)
    assert set(GROUPS["arms"]) | set(GROUPS["legs"]) | set(GROUPS["head"]) == set(JOINTS)
    with pytest.raises(EditError, match="unknown joint or group 'tail'"):
        joints_of("tail")


def test_values_are_quantized_to_what_a_page_holds_and_undone() -> None:
    e = editor()
    e.set_value(0, "r_elbow", 40.0)
    assert e.step(0)["r_elbow"] == quantize(40.0) == 39.99
    assert deg_to_raw(e.step(0)["r_elbow"]) == deg_to_raw(40.0)
    assert e.nudge(0, "r_elbow", 1.0) == quantize(40.99)
    e.set_value(0, "head_pan", None)
    assert "head_pan" not in e.step(0)
    assert e.undo() and e.step(0)["head_pan"] == 11.25
    assert e.undo() and e.undo() and e.step(0)["r_elbow"] == 22.5
    assert not e.undo()
    with pytest.raises(EditError, match="unknown joint"):
        e.set_value(0, "r_tail", 3.0)
    with pytest.raises(EditError, match="no step 5"):
        e.set_value(4, "r_elbow", 3.0)


def test_steps_insert_duplicate_delete_reorder_and_undo() -> None:
    e = editor()
    original = [dict(s) for s in e.steps]
    assert e.insert_step(1) == 1
    assert e.steps[1]["r_elbow"] == 22.5 and e.steps[1]["time"] == 100  # the pose before it
    assert e.duplicate_step(2) == 3 and e.steps[3] == e.steps[2]
    e.delete_step(0)
    assert len(e.steps) == 3
    assert e.move_step(2, -2) == 0
    with pytest.raises(EditError):
        e.move_step(0, -1)
    e.set_time(0, time=80, pause=3)
    assert (e.steps[0]["time"], e.steps[0]["pause"]) == (80, 3)
    while e.undo():
        pass
    assert e.steps == original


def test_header_fields_and_undo() -> None:
    e = editor()
    e.set_field("name", "hello")
    e.set_field("next", 4)
    e.set_field("number", 201)
    assert (e.page["name"], e.page["next"], e.page["number"]) == ("hello", 4, 201)
    e.undo()
    assert e.page["number"] == 200
    with pytest.raises(EditError, match="unknown page field"):
        e.set_field("colour", 3)


def test_mirror_gives_each_side_the_negated_angle() -> None:
    e = editor()
    e.mirror(0, "right")  # the left arm does what the right arm does
    s = e.step(0)
    assert (s["l_shoulder_pitch"], s["l_elbow"]) == (45.0, -22.5)
    assert s["r_shoulder_pitch"] == -45.0 and s["head_pan"] == 11.25
    assert "l_shoulder_roll" not in s
    e.undo()
    e.mirror(0)  # swap: the whole step mirrored
    s = e.step(0)
    assert (s["l_shoulder_pitch"], s["l_elbow"], s["head_pan"]) == (45.0, -22.5, -11.25)
    assert "r_shoulder_pitch" not in s and "r_elbow" not in s
    assert mirror_name("r_knee") == "l_knee" and mirror_name("head_tilt") == "head_tilt"


def test_mirrored_stock_pose_matches_the_library() -> None:
    # Page 1 (stand) is symmetric: mirroring it (swap) gives it back, raw word for raw word.
    from robot_daemon.motion.action.library import load_library

    lib = load_library()
    table = textfile.page_to_dict(lib.page(1))
    e = PageEditor(table)
    e.mirror(0)
    assert e.step(0) == table["step"][0]


def test_capture_stores_present_angles_of_the_chosen_joints() -> None:
    e = editor()
    present = {j: 0.0 for j in JOINTS} | {"r_shoulder_pitch": -75.3, "r_elbow": 12.04}
    stored = e.capture(1, present, joints_of("right_arm"))
    assert stored == {"r_shoulder_pitch": quantize(-75.3), "r_shoulder_roll": 0.0, "r_elbow": 12.04}
    assert e.step(1)["r_elbow"] == 12.04 and "l_elbow" not in e.step(1)
    e.undo()
    assert e.step(1) == {"time": 60, "pause": 5, "r_shoulder_pitch": 22.5}
    with pytest.raises(EditError, match="no present position"):
        e.capture(1, {"r_elbow": 1.0}, ["r_knee"])


def test_step_seconds_follow_the_page_speed() -> None:
    page = blank_page(3)
    assert step_seconds(page, {"time": 125}) == pytest.approx(1.0)
    page["speed"] = 64
    assert step_seconds(page, {"time": 125}) == pytest.approx(0.5)
