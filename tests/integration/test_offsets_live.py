"""Offsets set live through the ``offsets`` verb: the goal on the bus shifts at once, the config
reply shows them, they are saved to the user config, and only admins may set them."""

from __future__ import annotations

import tomllib
from collections.abc import Iterator
from pathlib import Path

import pytest

from clients.robot import Robot
from robot_daemon.bus.tables import MX28
from schemas import units
from schemas.errors import (
    ForbiddenError,
    InvalidCommandError,
    OutOfRangeError,
    UnavailableError,
)
from schemas.messages import decode_dict
from schemas.roles import Role
from tests.fixtures.system import RunningSystem, start_system
from tests.integration.test_auth import PASSWORDS, make_users, raw_replies


@pytest.fixture(scope="module")
def system() -> Iterator[RunningSystem]:
    with start_system(gateway=False) as running:
        yield running


def goal_raw(robot: Robot, dxl_id: int) -> int | None:
    """The servo's goal register; None when this read went unanswered (a loaded machine's
    emulator may miss the daemon's reply margin: the caller asks again)."""
    try:
        data = robot.registers(dxl_id, MX28.GOAL_POSITION.reg.address, 2)["data"]
    except UnavailableError:
        return None
    return data[0] | data[1] << 8


def wait_goal(robot: Robot, dxl_id: int, wanted: int) -> int | None:
    """The servo's goal register once it reads ``wanted`` (each read is a bus round trip
    through the arbiter; a bounded number of them)."""
    got = goal_raw(robot, dxl_id)
    for _ in range(100):
        if got == wanted:
            break
        robot.wait_for("joints")  # one more tick written
        got = goal_raw(robot, dxl_id)
    return got


def test_a_nudge_shifts_the_goal_on_the_bus_and_undo_restores_it(
    system: RunningSystem, tmp_path: Path
) -> None:
    with system.robot_client("calibration") as robot, robot.control("calibration"):
        cal = robot.calibration
        assert cal.offsets["r_knee"] == 0.0
        try:
            _nudge_mirror_save_undo(robot, tmp_path)
        finally:
            cal.reset()  # the module's system is shared: no offset outlives this test
        assert set(cal.refresh().values()) == {0.0}


def _nudge_mirror_save_undo(robot: Robot, tmp_path: Path) -> None:
    cal = robot.calibration
    cal.reference_pose(duration=0.2)
    centre = units.POSITION_CENTER
    assert wait_goal(robot, 13, centre) == centre
    cal.nudge("r_knee", 4.5)
    shifted = centre + round(4.5 / units.DEG_PER_UNIT)
    assert wait_goal(robot, 13, shifted) == shifted  # the daemon applied it, no restart
    assert (
        next(j["offset_deg"] for j in robot.config()["joints"] if j["name"] == "r_knee") == 4.5
    )
    cal.mirror("r_knee")
    assert cal.offsets["l_knee"] == -4.5
    assert wait_goal(robot, 14, centre - round(4.5 / units.DEG_PER_UNIT)) == centre - 51
    path = cal.save(tmp_path / "config.toml")
    saved = tomllib.loads(path.read_text())["robot"]["joints"]
    assert saved["r_knee"]["offset_deg"] == 4.5 and saved["l_knee"]["offset_deg"] == -4.5
    cal.undo()  # the mirror
    assert cal.offsets["l_knee"] == 0.0 and cal.offsets["r_knee"] == 4.5
    cal.undo()  # the nudge
    assert wait_goal(robot, 13, centre) == centre


def test_bad_offsets_are_refused_naming_the_field(system: RunningSystem) -> None:
    with system.robot_client("bad offsets") as robot, robot.control("bad"):
        with pytest.raises(OutOfRangeError, match="beyond"):
            robot.command("offsets", op="set", offsets={"r_knee": 90.0})
        with pytest.raises(InvalidCommandError, match="unknown joint"):
            robot.command("offsets", op="set", offsets={"r_kneee": 1.0})
        assert robot.calibration.refresh()["r_knee"] == 0.0


def test_setting_offsets_on_the_operator_key_is_forbidden(system: RunningSystem) -> None:
    with system.robot_client("sneaky") as robot, robot.control("sneaky"):
        (reply,) = raw_replies(
            robot,
            robot.keys.cmd("offsets"),
            op="set",
            offsets={"r_knee": 1.0},
            lease_token=robot._lease.token,
        )
        assert reply.err is not None
        assert decode_dict(reply.err.payload.to_bytes())["code"] == "forbidden"


def test_an_operator_may_read_but_not_set_offsets(tmp_path: Path) -> None:
    users = make_users(tmp_path)
    with (
        start_system(gateway=False, extra_args=["--auth", str(users)]) as system,
        Robot(system.endpoint, system.robot, user="op", password=PASSWORDS["op"]) as robot,
    ):
        assert robot.role == Role.OPERATOR
        assert robot.calibration.refresh()["r_knee"] == 0.0
        with robot.control("operator"), pytest.raises(ForbiddenError) as info:
            robot.calibration.nudge("r_knee", 1.0)
        assert info.value.role == "admin"
        assert (
            raw_replies(robot, robot.keys.admin("offsets"), op="set", offsets={"r_knee": 1.0})
            == []
        )
