"""Two simulated robots behind an authenticated router (`darwin router --auth`): the router's
access control enforces the roles for everyone who goes through it."""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from clients.robot import Robot
from schemas.errors import ForbiddenError, RobotUnreachableError
from schemas.roles import Role
from tests.fixtures.fleet import RunningRouter, start_router
from tests.fixtures.system import RunningSystem, run_darwin, start_system
from tests.integration.test_auth import PASSWORDS, make_users


@dataclass
class Fleet:
    router: RunningRouter
    robots: list[RunningSystem]
    directory: Path


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    directory = tmp_path_factory.mktemp("fleet")
    users = make_users(directory)
    for robot in ("r1", "r2"):
        (directory / f"{robot}.pw").write_text(f"{robot}-robot-password\n")
        done = run_darwin("users", "add", robot, "--role", "robot", "--password-file",
                          str(directory / f"{robot}.pw"), "--users", str(users))
        assert done.returncode == 0, done.stderr
    with start_router("--auth", str(users)) as router:
        systems = []
        try:
            for robot in ("r1", "r2"):
                login = ["--user", robot, "--password-file", str(directory / f"{robot}.pw")]
                ctx = start_system(router=router.endpoint, gateway=False, extra_args=login)
                systems.append(ctx)
            robots = [ctx.__enter__() for ctx in systems]
            yield Fleet(router, robots, directory)
        finally:
            for ctx in reversed(systems):
                ctx.__exit__(None, None, None)


def test_observers_watch_both_robots_but_cannot_command_them(fleet: Fleet) -> None:
    for system in fleet.robots:
        with Robot(fleet.router.endpoint, system.robot, user="obs",
                   password=PASSWORDS["obs"]) as robot:
            assert robot.role == Role.OBSERVER
            robot.wait_for("joints", timeout=15.0)
            assert robot.config()["robot"] == system.robot
            with pytest.raises(ForbiddenError, match="operator"):
                robot.command("halt")


def test_an_operator_drives_one_robot_through_the_router(fleet: Fleet) -> None:
    first = fleet.robots[0]
    with Robot(fleet.router.endpoint, first.robot, user="op", password=PASSWORDS["op"]) as robot:
        assert robot.role == Role.OPERATOR
        with robot.control("fleet operator"):
            assert robot.command("led", eye=[5, 5, 5])
            with pytest.raises(ForbiddenError, match="admin"):
                robot.registers(19, 25, data=[1])


def test_the_router_refuses_a_wrong_password(fleet: Fleet) -> None:
    with pytest.raises(RobotUnreachableError):
        Robot(fleet.router.endpoint, fleet.robots[0].robot, user="op", password="wrong-password")


def test_darwin_list_logs_in_to_the_router(fleet: Fleet) -> None:
    login = ["--user", "obs", "--password-file", str(fleet.directory / "obs.pw")]
    done = run_darwin("list", "--connect", fleet.router.endpoint, "--json", *login)
    assert done.returncode == 0, done.stderr
    names = {r["name"] for r in json.loads(done.stdout)}
    assert {s.robot for s in fleet.robots} <= names
    refused = run_darwin("list", "--connect", fleet.router.endpoint, "--json")
    assert refused.returncode != 0 and "nothing answers" in refused.stderr
