"""A router that goes away and comes back (issue 26): a robot that protects its own endpoint
(``--auth``) and joined an authenticated router says when the router loses sight of it and when
it sees it again; ``darwin list`` says the router is unreachable while it is away and lists the
robot again once it is back; Foxglove (through the router) shows the robot unreachable, then
clears that; the robot's own endpoint keeps serving throughout."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import pytest

from clients.fleet import discover_at
from schemas.errors import RobotUnreachableError
from schemas.session import Credentials, free_tcp_port
from tests.fixtures.fleet import start_router
from tests.fixtures.system import spawn_darwin, start_system, stop_group
from tests.foxglove_ws import FoxgloveClient
from tests.integration.test_auth import PASSWORDS, add_user, make_users

DEADLINE_S = 60.0  # a failure bound only


def eventually(check: Callable[[], bool]) -> bool:
    deadline = time.monotonic() + DEADLINE_S
    while time.monotonic() < deadline:
        if check():
            return True
    return False


def listed(endpoint: str, robot: str) -> bool:
    try:
        records = discover_at(endpoint, creds=Credentials("op", PASSWORDS["op"]))
    except RobotUnreachableError:
        return False
    return robot in {r.name for r in records}


def test_a_protected_robot_rejoins_a_restarted_router_and_says_so(tmp_path: Path) -> None:
    users = make_users(tmp_path)
    pw = add_user(users, "rb", "robot", "robot-password-1")
    port = free_tcp_port()
    first = start_router("--auth", str(users), port=port)
    router = first.__enter__()
    own = f"tcp/127.0.0.1:{free_tcp_port()}"
    login = ["--user", "rb", "--password-file", str(pw), "--auth", str(users), "--listen", own]
    system = start_system(router=router.endpoint, gateway=False, extra_args=login)
    try:
        robot = system.__enter__()
        fox_listen = f"127.0.0.1:{free_tcp_port()}"
        foxglove = spawn_darwin("foxglove", "--connect", router.endpoint, "--robot", robot.robot,
                                "--listen", fox_listen, "--user", "obs", "--password-file",
                                str(tmp_path / "obs.pw"))
        try:
            assert eventually(lambda: listed(router.endpoint, robot.robot))
            assert foxglove.stdout is not None
            # Its address line, after any warning it logs first (the loaded robot's loop).
            assert any(line.startswith("foxglove: ") for line in foxglove.stdout)
            fc = FoxgloveClient.open(f"ws://{fox_listen}")
            first.__exit__(None, None, None)
            # Foxglove says the robot is away (its last values are not live data) …
            fc.status_matching(f"robot {robot.robot} is unreachable")
            robot.wait_line(lambda ln: "does not see this robot" in ln, DEADLINE_S)
            with pytest.raises(RobotUnreachableError, match="nothing answers"):
                discover_at(router.endpoint, creds=Credentials("op", PASSWORDS["op"]))
            assert listed(own, robot.robot)  # its own endpoint serves while the router is away
            with start_router("--auth", str(users), port=port) as again:
                robot.wait_line(lambda ln: "sees this robot again" in ln, DEADLINE_S)
                assert eventually(lambda: listed(again.endpoint, robot.robot))
                # … and clears it once the robot is back.
                fc.until(lambda c: any(t.get("op") == "removeStatus" for t in c.texts),
                         DEADLINE_S)
                fc.close()
        finally:
            stop_group(foxglove)
            if foxglove.stdout is not None:
                foxglove.stdout.close()
            system.__exit__(None, None, None)
    finally:
        first.__exit__(None, None, None)
