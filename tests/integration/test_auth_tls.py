"""`darwin up --secure`: TLS with the certificates of `darwin certs`, passwords or (``--mtls``)
client certificates whose common name is the user, and access control on those names."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from clients.robot import Robot
from schemas.errors import ForbiddenError, RobotUnreachableError
from schemas.roles import Role
from schemas.session import Credentials, free_tcp_port
from tests.fixtures.system import RunningSystem, run_darwin, start_system
from tests.integration.test_auth import PASSWORDS, make_users


def secure_system(directory: Path, *extra: str) -> Iterator[RunningSystem]:
    certs = directory / "certs"
    done = run_darwin("certs", "--dir", str(certs), "--host", "127.0.0.1",
                      "--client", "obs", "--client", "op")
    assert done.returncode == 0, done.stderr
    args = ["--secure", "--certs", str(certs), "--auth", str(make_users(directory)),
            "--listen", f"tls/127.0.0.1:{free_tcp_port()}", *extra]
    with start_system(extra_args=args) as system:
        yield system


@pytest.fixture(scope="module")
def tls_system(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningSystem]:
    yield from secure_system(tmp_path_factory.mktemp("tls"))


@pytest.fixture(scope="module")
def mtls_system(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningSystem]:
    yield from secure_system(tmp_path_factory.mktemp("mtls"), "--mtls")


def ca_of(system: RunningSystem) -> str:
    arg = system.process.args[system.process.args.index("--certs") + 1]  # type: ignore[union-attr]
    return str(Path(arg) / "ca.pem")


def test_secure_listens_on_tls_and_a_plain_tcp_client_cannot_connect(
    tls_system: RunningSystem,
) -> None:
    assert tls_system.endpoint.startswith("tls/")
    plain = "tcp/" + tls_system.endpoint.split("/", 1)[1]
    creds = Credentials("op", PASSWORDS["op"])
    with pytest.raises(RobotUnreachableError):
        Robot(plain, tls_system.robot, credentials=creds)
    with Robot(tls_system.endpoint, tls_system.robot, credentials=Credentials(
        "op", PASSWORDS["op"], ca=ca_of(tls_system)
    )) as robot:
        assert robot.role == Role.OPERATOR
        robot.wait_for("joints", timeout=15.0)
        with robot.control("tls operator"):
            assert robot.command("led", eye=[1, 2, 3])


def test_a_client_that_does_not_trust_the_robot_certificate_cannot_connect(
    tls_system: RunningSystem, tmp_path: Path
) -> None:
    other = tmp_path / "other"
    assert run_darwin("certs", "--dir", str(other)).returncode == 0
    creds = Credentials("op", PASSWORDS["op"], ca=str(other / "ca.pem"))
    with pytest.raises(RobotUnreachableError):
        Robot(tls_system.endpoint, tls_system.robot, credentials=creds)


def test_mtls_identifies_by_certificate_common_name(mtls_system: RunningSystem) -> None:
    certs = Path(ca_of(mtls_system)).parent
    as_obs = Credentials(cert=str(certs / "obs.pem"), key=str(certs / "obs.key"),
                         ca=str(certs / "ca.pem"))
    with Robot(mtls_system.endpoint, mtls_system.robot, credentials=as_obs) as robot:
        assert robot.role == Role.OBSERVER
        robot.wait_for("joints", timeout=15.0)
        with pytest.raises(ForbiddenError, match="operator"):
            robot.acquire()
    as_op = Credentials(cert=str(certs / "op.pem"), key=str(certs / "op.key"),
                        ca=str(certs / "ca.pem"))
    with Robot(mtls_system.endpoint, mtls_system.robot, credentials=as_op) as robot:
        assert robot.role == Role.OPERATOR


def test_mtls_refuses_an_untrusted_client_certificate(
    mtls_system: RunningSystem, tmp_path: Path
) -> None:
    # A certificate with a known user's name, signed by another CA: refused at connection.
    other = tmp_path / "other"
    assert run_darwin("certs", "--dir", str(other), "--client", "op").returncode == 0
    certs = Path(ca_of(mtls_system)).parent
    forged = Credentials(cert=str(other / "op.pem"), key=str(other / "op.key"),
                         ca=str(certs / "ca.pem"))
    with pytest.raises(RobotUnreachableError):
        Robot(mtls_system.endpoint, mtls_system.robot, credentials=forged)
    no_cert = Credentials(ca=str(certs / "ca.pem"))
    with pytest.raises(RobotUnreachableError):
        Robot(mtls_system.endpoint, mtls_system.robot, credentials=no_cert)
