"""Roles and authentication against a real `darwin up --auth` (emulator, daemon, gateway):
Zenoh's user/password login and access control, the client's role check, the arbiter's admin
keys and a watch-only legacy gateway."""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from clients.robot import Robot
from robot_daemon.bus.tables import MX28
from schemas.errors import ForbiddenError, RefusedError, RobotUnreachableError
from schemas.keys import Keys
from schemas.messages import command_payload, decode_dict
from schemas.roles import Role
from schemas.sim_control import SimControl
from tests.fixtures.emulator import darwin_command
from tests.fixtures.system import RunningSystem, run_darwin, start_system
from tests.legacy_client import LegacyClient

PASSWORDS = {"obs": "observer-pass-1", "op": "operator-pass-1", "adm": "admin-pass-123"}
ROLES = {"obs": "observer", "op": "operator", "adm": "admin"}


def add_user(users: Path, name: str, role: str, password: str) -> Path:
    """``darwin users add`` into ``users``; the password's file (beside it) is returned."""
    pw = users.parent / f"{name}.pw"
    pw.write_text(password + "\n")
    done = run_darwin("users", "add", name, "--role", role, "--password-file", str(pw),
                      "--users", str(users))
    assert done.returncode == 0, done.stderr
    return pw


def make_users(directory: Path) -> Path:
    users = directory / "users.toml"
    for name, role in ROLES.items():
        add_user(users, name, role, PASSWORDS[name])
    return users


@pytest.fixture(scope="module")
def auth_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    directory = tmp_path_factory.mktemp("auth")
    make_users(directory)
    return directory


@pytest.fixture(scope="module")
def auth_system(auth_dir: Path) -> Iterator[RunningSystem]:
    users = auth_dir / "users.toml"
    with start_system(extra_args=["--auth", str(users), "--adapter-role", "observer"]) as system:
        yield system


def login(system: RunningSystem, user: str, **kwargs: object) -> Robot:
    return Robot(system.endpoint, system.robot, user=user, password=PASSWORDS[user],
                 timeout=5.0, **kwargs)  # type: ignore[arg-type]


def raw_replies(robot: Robot, key: str, **fields: object) -> list[object]:
    """Replies to a query sent past the client's role check: what access control lets by."""
    payload = command_payload(robot.client_id, **fields)
    return list(robot.session.get(key, payload=payload, timeout=5.0))


def test_an_observer_watches_and_reads_but_every_command_is_refused_naming_the_role(
    auth_system: RunningSystem,
) -> None:
    with login(auth_system, "obs") as robot:
        assert robot.role == Role.OBSERVER
        robot.wait_for("joints", timeout=15.0)
        assert robot.config()["robot"] == auth_system.robot
        with pytest.raises(ForbiddenError) as info:
            robot.command("walk", op="start", x=0.01)
        assert info.value.role == "operator" and "operator" in str(info.value)
        with pytest.raises(ForbiddenError, match="operator"):
            robot.acquire()
        # Zenoh's access control is what enforces it: past the client's check the query is
        # dropped by the daemon's session, so nothing answers.
        assert raw_replies(robot, robot.keys.cmd("lease"), op="acquire") == []
        assert raw_replies(robot, robot.keys.cmd("halt")) == []


def test_an_observer_reads_the_gait_parameters_but_may_not_set_them(
    auth_system: RunningSystem,
) -> None:
    with login(auth_system, "obs") as robot:
        params = robot.command("walk_params")["params"]  # a read: on read/walk_params
        assert params["period_time"] > 0
        change = {"period_time": params["period_time"] + 10}
        with pytest.raises(ForbiddenError) as info:
            robot.command("walk_params", set=change)
        assert info.value.role == "operator"
        # Past the client's check: the set on cmd/ is dropped by access control, and the read
        # key refuses anything but the read (the arbiter), so the gait never changed.
        assert raw_replies(robot, robot.keys.cmd("walk_params"), set=change) == []
        (reply,) = raw_replies(robot, robot.keys.read("walk_params"), set=change)
        assert reply.err is not None  # type: ignore[attr-defined]
        assert decode_dict(reply.err.payload.to_bytes())["code"] == "forbidden"  # type: ignore[attr-defined]
        assert robot.command("walk_params")["params"]["period_time"] == params["period_time"]


def test_the_emulator_control_refuses_operators_and_observers_naming_the_admin_role(
    auth_system: RunningSystem,
) -> None:
    for user in ("obs", "op"):
        with login(auth_system, user) as robot:
            # Access control would drop the query unanswered ("no emulator answers", after
            # the whole timeout); the early check names the role instead.
            with pytest.raises(ForbiddenError) as info:
                SimControl(robot.session, auth_system.robot).call("faults")
            assert info.value.role == "admin" and "emulator" in str(info.value)
    with login(auth_system, "adm") as robot:
        assert isinstance(SimControl(robot.session, auth_system.robot).call("faults"), dict)


def test_an_operator_drives_but_admin_only_operations_are_refused(
    auth_system: RunningSystem,
) -> None:
    with login(auth_system, "op") as robot:
        assert robot.role == Role.OPERATOR
        with robot.control("operator test"):
            applied = robot.command("led", eye=[10, 20, 30])
            assert applied
            assert "params" in robot.command("walk_params")  # an operator reads the gait
            with pytest.raises(ForbiddenError) as info:
                robot.registers(19, 25, data=[1])  # a servo's LED: still a register write
            assert info.value.role == "admin"
            with pytest.raises(ForbiddenError, match="admin"):
                robot.command("pages", op="delete", number=200)
        keys = Keys(auth_system.robot)
        assert raw_replies(robot, keys.admin("registers"), id=19, address=25, data=[1]) == []
        assert raw_replies(robot, keys.sim_control, op="faults") == []


def test_an_admin_writes_registers_and_reaches_the_emulator(auth_system: RunningSystem) -> None:
    with login(auth_system, "adm") as robot:
        assert robot.role == Role.ADMIN
        with robot.control("admin test"):
            # Past access control and the role checks, the write meets the daemon's own switch
            # (this one runs without --allow-hardware-writes).
            with pytest.raises(RefusedError, match="--allow-hardware-writes"):
                robot.registers(200, 24, data=[0])  # CM-730 DXL_POWER
            # An admin-only operation that succeeds is answered on the admin key it came on.
            assert robot.command("pages", op="reload")["op"] == "reload"
            # The same write sent on cmd/ (where operators may send) is refused by the arbiter:
            # only the admin key, which access control gives to admins, carries it.
            (reply,) = raw_replies(
                robot, robot.keys.cmd("registers"), id=19, address=25, data=[0],
                lease_token=robot._lease.token,
            )
            assert reply.err is not None  # type: ignore[attr-defined]
            assert decode_dict(reply.err.payload.to_bytes())["code"] == "forbidden"  # type: ignore[attr-defined]
        replies = raw_replies(robot, robot.keys.sim_control, op="faults")
        assert len(replies) == 1  # the emulator, behind the daemon, answers an admin


def test_a_wrong_password_or_no_login_is_refused_at_connection(
    auth_system: RunningSystem,
) -> None:
    with pytest.raises(RobotUnreachableError, match="as op"):
        Robot(auth_system.endpoint, auth_system.robot, user="op", password="not-the-password")
    with pytest.raises(RobotUnreachableError, match="--user"):
        Robot(auth_system.endpoint, auth_system.robot)


def test_the_gateway_of_an_observer_identity_answers_commands_with_an_error(
    auth_system: RunningSystem,
) -> None:
    assert auth_system.gateway is not None
    host, port = auth_system.gateway
    with LegacyClient(host, port) as client:
        client.send({"operate": {"all": 0, "id": 1, "position": 10}})
        err = client.recv_error()
        assert err["code"] == "forbidden" and "operator" in err["message"], err
        client.send({"monitor": {"motors": 1}})  # watching still works
        motors = client.recv_until(lambda m: "motors" in m.get("monitor", {}))
        assert motors["monitor"]["motors"]


def test_gateway_role_observer_caps_an_operator_identity(
    auth_system: RunningSystem, auth_dir: Path
) -> None:
    proc = subprocess.Popen(
        darwin_command(
            "gateway", "--connect", auth_system.endpoint, "--robot", auth_system.robot,
            "--user", "op", "--password-file", str(auth_dir / "op.pw"), "--role", "observer",
            "--listen", "127.0.0.1:0",
        ),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )
    try:
        assert proc.stdout is not None
        line = next(x for x in proc.stdout if x.startswith("gateway: "))
        host, _, port = line.split(" ", 1)[1].strip().rpartition(":")
        assert host == "127.0.0.1"  # loopback unless told otherwise
        with LegacyClient(host, int(port)) as client:
            client.send({"walk": {"a": 0, "stop": 0, "x": 10, "y": 0}})
            err = client.recv_error()
            assert err["code"] == "forbidden", err
    finally:
        proc.terminate()
        proc.wait(timeout=10)
        if proc.stdout is not None:
            proc.stdout.close()


def test_an_operator_flooding_power_torque_and_registers_powers_and_re_arms_nothing(
    auth_system: RunningSystem,
) -> None:
    """The reset button pressed: an operator holding the lease hammers every way back to power
    (the `power` verb on the admin key and on cmd/, torque on, a TORQUE_LIMIT write) and none of
    it powers or re-arms a servo; only an admin's `power` does."""
    limit = MX28.TORQUE_LIMIT.reg.address
    with login(auth_system, "adm") as admin, login(auth_system, "op") as robot:
        sim = SimControl(admin.session, auth_system.robot)
        admin.wait_for("status", lambda s: s.state in ("running", "degraded"), timeout=30)
        sim.call("dxl_power_loss")
        robot.wait_for("status", lambda s: s.state == "servos_off", timeout=30)
        try:
            with robot.control("flood"):
                token = robot._lease.token
                for _ in range(20):
                    # Past the client's own role check, as a hostile client would send them.
                    assert raw_replies(robot, robot.keys.admin("power"), op="on") == []
                    assert raw_replies(robot, robot.keys.admin("registers"), id=13,
                                       address=limit, data=[255, 3]) == []
                    for verb, fields in (
                        ("power", {"op": "on"}),
                        ("registers", {"id": 13, "address": limit, "data": [255, 3]}),
                        ("torque", {"enable": True}),
                    ):
                        (reply,) = raw_replies(
                            robot, robot.keys.cmd(verb), lease_token=token, **fields
                        )
                        assert reply.err is not None, verb  # type: ignore[attr-defined]
                    with pytest.raises(ForbiddenError, match="admin"):
                        robot.power(True)
                tick = robot.wait_for("status", timeout=10).loop["ticks"]
                robot.wait_for("status", lambda s: s.loop["ticks"] > tick + 125, timeout=30)
            state = sim.call("state")
            assert not state["dxl_power"] and not state["servo_power"]
            assert all(s["torque_limit"] == 0 or not s["powered"] for s in state["servos"].values())
            assert robot.wait_for("status", timeout=10).state == "servos_off"
        finally:
            with admin.control("restore"):
                admin.power(True)
            admin.wait_for("status", lambda s: s.state in ("running", "degraded"), timeout=30)
