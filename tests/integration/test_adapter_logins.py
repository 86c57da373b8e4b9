"""Who the adapters and the UI of `darwin up` log in as: an identity of their own with the least
role they need, never the robot's (which may do everything). Real routers, daemons, gateways
and the real TUI process (under a pseudo-terminal)."""

from __future__ import annotations

import contextlib
import os
import pty
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from clients.robot import Robot
from schemas.roles import Role
from schemas.session import free_tcp_port
from tests.fixtures.emulator import darwin_command
from tests.fixtures.fleet import RunningRouter, start_router
from tests.fixtures.system import REPO, run_darwin, start_system, stop_group
from tests.integration.test_auth import add_user as auth_user
from tests.integration.test_auth import make_users
from tests.legacy_client import LegacyClient

DEADLINE_S = 60.0


def add_user(users: Path, name: str, role: str) -> Path:
    return auth_user(users, name, role, f"{name}-password-1")


@pytest.fixture(scope="module")
def users(tmp_path_factory: pytest.TempPathFactory) -> Path:
    users = make_users(tmp_path_factory.mktemp("adapter-logins"))
    add_user(users, "r3", "robot")
    add_user(users, "gw", "observer")  # a gateway's own identity on the router
    return users


@pytest.fixture(scope="module")
def router(users: Path) -> Iterator[RunningRouter]:
    with start_router("--auth", str(users)) as router:
        yield router


def robot_login(users: Path) -> list[str]:
    return ["--user", "r3", "--password-file", str(users.parent / "r3.pw")]


def test_under_a_router_the_gateway_logs_in_as_its_own_identity_not_the_robots(
    router: RunningRouter, users: Path, tmp_path: Path
) -> None:
    config = tmp_path / "adapters.toml"
    config.write_text(f'[adapters.gateway]\nuser = "gw"\npassword_file = "{users.parent}/gw.pw"\n')
    args = [*robot_login(users), "--config", str(config), "--ros2"]
    with start_system(router=router.endpoint, extra_args=args) as system:
        assert system.gateway is not None
        with LegacyClient(*system.gateway) as client:
            # gw is an observer on the router: as the robot (role robot) this would move it.
            client.send({"walk": {"a": 0, "stop": 0, "x": 10, "y": 0}})
            err = client.recv_error()
            assert err["code"] == "forbidden" and "operator" in err["message"], err
            client.send({"monitor": {"motors": 1}})
            assert client.recv_until(lambda m: "motors" in m.get("monitor", {}))
        # An adapter with no identity of its own is not started as the robot.
        line = system.wait_line(lambda x: x.startswith("ros2: "))
        assert line.startswith("ros2: none (") and "r3" in line and "[adapters.ros2]" in line


def test_adapter_roles_are_per_adapter(tmp_path: Path, users: Path) -> None:
    """`darwin up --auth`: the gateway of `--adapter-role gateway=observer` is watch-only while
    the others keep the default (operator)."""
    extra = ["--auth", str(users), "--adapter-role", "gateway=observer"]
    with start_system(extra_args=extra) as system:
        assert system.gateway is not None
        with LegacyClient(*system.gateway) as client:
            client.send({"operate": {"all": 0, "id": 1, "position": 10}})
            assert client.recv_error()["code"] == "forbidden"
    done = run_darwin("up", "--adapter-role", "gateway=king", "--no-gateway")
    assert done.returncode != 0 and "king" in done.stderr and "observer" in done.stderr
    assert "Traceback" not in done.stderr


def test_a_watch_only_foxglove_reads_the_gait_parameters_but_cannot_set_them(
    users: Path,
) -> None:
    pytest.importorskip("foxglove")
    from tests.foxglove_ws import FoxgloveClient

    listen = f"127.0.0.1:{free_tcp_port()}"
    extra = ["--auth", str(users), "--foxglove", "--foxglove-listen", listen,
             "--adapter-role", "foxglove=observer"]
    with start_system(extra_args=extra, gateway=False) as system:
        line = system.wait_line(lambda x: x.startswith("foxglove: "))
        with FoxgloveClient.open(line.split(" ", 1)[1].strip()) as fc:
            params = {p["name"]: p["value"] for p in fc.get_parameters([], "all")}
            assert params["walk/period_time"] > 0  # darwin-foxglove, an observer, reads them
            old = params["walk/foot_height"]
            reply = fc.set_parameters([{"name": "walk/foot_height", "value": old + 5,
                                        "type": "float64"}], "w1")
            assert reply[0]["value"] == old
            assert "operator" in fc.status_matching("walking parameters not changed")["message"]


# -- the UI of `darwin up --tui` --------------------------------------------------------------


@contextlib.contextmanager
def up_with_tui(args: list[str], env: dict[str, str]) -> Iterator[subprocess.Popen[bytes]]:
    """`darwin up … --tui` on a pseudo-terminal (the UI needs one), drained by a thread."""
    master, slave = pty.openpty()
    proc = subprocess.Popen(
        darwin_command("up", *args, "--tui"), stdin=slave, stdout=slave, stderr=slave,
        cwd=REPO, env=env, start_new_session=True,
    )
    os.close(slave)

    def drain() -> None:
        with contextlib.suppress(OSError):
            while os.read(master, 65536):
                pass

    threading.Thread(target=drain, daemon=True).start()
    try:
        yield proc  # type: ignore[misc]
    finally:
        stop_group(proc)  # type: ignore[arg-type]
        os.close(master)


def tui_process(up: subprocess.Popen[bytes]) -> int:
    """The pid of the UI that `darwin up` started (its child running
    `robot_daemon.launch.cli tui`)."""
    deadline = time.monotonic() + DEADLINE_S
    while time.monotonic() < deadline:
        assert up.poll() is None, f"darwin up exited with {up.returncode}"
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            with contextlib.suppress(OSError):
                stat = (entry / "stat").read_text()
                ppid = int(stat.rsplit(")", 1)[1].split()[1])
                argv = (entry / "cmdline").read_bytes().split(b"\0")
                if ppid == up.pid and b"tui" in argv and b"robot_daemon.launch.cli" in argv:
                    return int(entry.name)
        time.sleep(0.1)  # a process appearing has no event to wait on
    raise AssertionError("darwin up --tui started no UI")


def argv_of(pid: int) -> list[str]:
    return [a.decode() for a in Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0") if a]


def environ_of(pid: int) -> dict[str, str]:
    raw = Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
    return dict(x.decode().split("=", 1) for x in raw if b"=" in x)


def clean_env(tmp_path: Path, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("DARWIN_")}
    env["DARWIN_CLIENT_CONFIG"] = str(tmp_path / "no-client.toml")  # not this machine's file
    return env | extra | {"PYTHONUNBUFFERED": "1"}


def option(argv: list[str], name: str) -> str | None:
    return argv[argv.index(name) + 1] if name in argv else None


def test_the_ui_of_up_auth_logs_in_as_an_operator_identity_of_its_own(
    tmp_path: Path, users: Path
) -> None:
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    args = ["--auth", str(users), "--listen", endpoint, "--no-gateway", "--camera", "none",
            "--robot", "tuiauth"]
    with up_with_tui(args, clean_env(tmp_path)) as up:
        argv = argv_of(tui_process(up))
        user, password_file = option(argv, "--user"), option(argv, "--password-file")
        assert user == "darwin-tui" and password_file is not None, argv
        # The same login, used here, is an operator at the robot (not admin, not the robot).
        password = Path(password_file).read_text().strip()
        with Robot(endpoint, "tuiauth", user=user, password=password, timeout=10.0) as robot:
            assert robot.role == Role.OPERATOR


def test_the_ui_of_up_router_logs_in_as_the_person_not_the_robot(
    router: RunningRouter, users: Path, tmp_path: Path
) -> None:
    person = clean_env(tmp_path, DARWIN_USER="op",
                       DARWIN_PASSWORD_FILE=str(users.parent / "op.pw"))
    args = ["--router", router.endpoint, *robot_login(users), "--no-gateway", "--camera", "none",
            "--robot", "tuirouter"]
    with up_with_tui(args, person) as up:
        pid = tui_process(up)
        argv, env = argv_of(pid), environ_of(pid)
        assert option(argv, "--user") is None and "r3.pw" not in " ".join(argv), argv
        assert env.get("DARWIN_USER") == "op"  # the person's own login, from their environment
    # When the person's login is the robot's, the UI is not started as the robot.
    robot_env = clean_env(tmp_path, DARWIN_USER="r3",
                          DARWIN_PASSWORD_FILE=str(users.parent / "r3.pw"))
    done = subprocess.run(
        darwin_command("up", "--router", router.endpoint, "--no-gateway", "--camera", "none",
                       "--robot", "tuirobot", "--tui"),
        capture_output=True, text=True, cwd=REPO, env=robot_env, timeout=120,
    )
    assert done.returncode == 2, done.stderr
    assert "--tui would log in as the robot (r3)" in done.stderr
    assert "Traceback" not in done.stderr


def test_the_login_of_whoever_starts_up_does_not_leak_into_the_adapters(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """An open robot started by someone whose environment carries their login (DARWIN_USER,
    DARWIN_PASSWORD, a client file): the adapters' login is only what `darwin up` gives them,
    so the gateway does not present that person's password to a robot with no logins (Zenoh
    refuses such a client) and works."""
    client_file = tmp_path / "client.toml"
    client_file.write_text('user = "alice"\npassword = "alice-password-1"\n')
    monkeypatch.setenv("DARWIN_USER", "alice")
    monkeypatch.setenv("DARWIN_PASSWORD", "alice-password-1")
    monkeypatch.setenv("DARWIN_CLIENT_CONFIG", str(client_file))
    with start_system() as system:
        assert system.gateway is not None
        with LegacyClient(*system.gateway) as client:
            client.send({"monitor": {"motors": 1}})
            assert client.recv_until(lambda m: "motors" in m.get("monitor", {}))
