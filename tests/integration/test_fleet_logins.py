"""Every way a user can start a robot that joins a router — open, authenticated or TLS router;
login by flags or by variables; the robot's own endpoint open, ``--auth`` or ``--secure`` —
either works (an operator of the router lists the robot) or stops at start with one line naming
what is wrong and the fix (docs/fleet.md has the table).

The routers are shared by every case; each case is one real ``darwin up`` (emulator, daemon)."""

from __future__ import annotations

import os
import subprocess
import threading
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from clients.fleet import discover
from schemas.keys import Keys
from schemas.session import Credentials, connect, free_tcp_port
from tests.fixtures.emulator import darwin_command
from tests.fixtures.fleet import RunningRouter, start_router
from tests.fixtures.system import REPO, run_darwin, stop_group
from tests.integration.test_auth import PASSWORDS, add_user, make_users

ROBOT_PW = "robot-password-1"
LIST_DEADLINE_S = 60.0  # a failure bound only: a working case lists the robot as soon as it can


@dataclass
class Routers:
    directory: Path
    users: Path
    certs: Path
    by_kind: dict[str, RunningRouter] = field(default_factory=dict)

    def endpoint(self, kind: str) -> str:
        if kind == "none":
            return f"tcp/127.0.0.1:{free_tcp_port()}"  # nothing listens there
        if kind == "tls-as-tcp":
            return "tcp/" + self.by_kind["tls"].endpoint.split("/", 1)[1]
        return self.by_kind[kind].endpoint


@pytest.fixture(scope="module")
def routers(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Routers]:
    directory = tmp_path_factory.mktemp("fleet-logins")
    users = make_users(directory)
    add_user(users, "rb", "robot", ROBOT_PW)
    certs = directory / "certs"
    done = run_darwin("certs", "--dir", str(certs), "--host", "127.0.0.1")
    assert done.returncode == 0, done.stderr
    found = Routers(directory, users, certs)
    with (
        start_router() as open_router,
        start_router("--auth", str(users)) as auth_router,
        start_router("--secure", "--auth", str(users), "--certs", str(certs),
                     scheme="tls") as tls_router,
    ):
        found.by_kind = {"open": open_router, "auth": auth_router, "tls": tls_router}
        yield found


@dataclass(frozen=True)
class Case:
    router: str  # open | auth | tls | tls-as-tcp | none (nothing there) | - (no --router)
    args: tuple[str, ...] = ()  # {pw} the robot's password file, {ca} the CA, {users}, {certs}
    env: tuple[tuple[str, str], ...] = ()
    refusal: str = ""  # empty: it works; else a piece of the one line it stops with


LOGIN = ("--user", "rb", "--password-file", "{pw}")
AUTH = ("--auth", "{users}")
SECURE = ("--secure", "--auth", "{users}", "--certs", "{certs}")
ENV_LOGIN = (("DARWIN_USER", "rb"), ("DARWIN_PASSWORD", ROBOT_PW))

CASES = {
    "open router": Case("open"),
    "open router, robot --auth": Case("open", AUTH),
    "auth router, login flags": Case("auth", LOGIN),
    "auth router, login flags, robot --auth (issue 26)": Case("auth", (*LOGIN, *AUTH)),
    "auth router, login variables, robot --auth": Case("auth", AUTH, ENV_LOGIN),
    "auth router, DARWIN_PASSWORD_FILE": Case(
        "auth", AUTH, (("DARWIN_USER", "rb"), ("DARWIN_PASSWORD_FILE", "{pw}"))),
    "tls router, --ca and login": Case("tls", (*LOGIN, "--ca", "{ca}")),
    "tls router, robot --secure": Case("tls", (*LOGIN, "--ca", "{ca}", *SECURE)),
    "auth router, no login": Case("auth", AUTH, refusal="it requires a login: pass --user"),
    "auth router, wrong password": Case(
        "auth", ("--user", "rb", "--password-file", "{wrong}"), refusal="check rb's password"),
    "auth router, admin login by variables": Case(
        "auth", AUTH, (("DARWIN_USER", "adm"), ("DARWIN_PASSWORD", PASSWORDS["adm"])),
        refusal="does not see this robot"),
    "auth router, operator login flags": Case(
        "auth", ("--user", "op", "--password-file", "{op}"), refusal="not op"),
    "nothing at --router": Case("none", LOGIN, refusal="cannot reach the router"),
    "tls router as tcp/": Case("tls-as-tcp", LOGIN, refusal="write --router tls/"),
    "tls router without --ca": Case("tls", LOGIN, refusal="also needs --ca"),
    "login flags without --router": Case("-", LOGIN, refusal="add --router ENDPOINT"),
    "DARWIN_PASSWORD without DARWIN_USER": Case(
        "auth", (), (("DARWIN_PASSWORD", ROBOT_PW),), refusal="needs a user name"),
    "missing password file": Case(
        "auth", ("--user", "rb", "--password-file", "/nonexistent/rb.pw"),
        refusal="cannot read the password file"),
    "robot --secure listening on tcp/": Case(
        "tls", (*LOGIN, "--ca", "{ca}", *SECURE, "--listen", "tcp/127.0.0.1:0"),
        refusal="write tls/"),
}


def _fill(text: str, routers: Routers) -> str:
    wrong = routers.directory / "wrong.pw"
    wrong.write_text("not-the-password\n")
    rb = routers.directory / "rb.pw"
    return text.format(pw=rb, ca=routers.certs / "ca.pem", users=routers.users,
                       certs=routers.certs, wrong=wrong, op=routers.directory / "op.pw")


def _start(case: Case, routers: Routers, err: Path) -> tuple[str, subprocess.Popen[str]]:
    robot = f"f{uuid.uuid4().hex[:8]}"
    cmd = ["up", "--robot", robot, "--no-gateway", "--camera", "none"]
    if case.router != "-":
        cmd += ["--router", routers.endpoint(case.router)]
    cmd += [_fill(a, routers) for a in case.args]
    env = {k: v for k, v in os.environ.items() if not k.startswith("DARWIN_")}
    env.update({k: _fill(v, routers) for k, v in case.env}, PYTHONUNBUFFERED="1",
               DARWIN_CLIENT_CONFIG=os.devnull)
    with err.open("w") as sink:  # a file, not a pipe nobody reads while the robot runs
        proc = subprocess.Popen(darwin_command(*cmd), stdout=subprocess.DEVNULL, stderr=sink,
                                text=True, cwd=REPO, env=env, start_new_session=True)
    return robot, proc


def _listed(routers: Routers, kind: str, robot: str) -> bool:
    """Whether an operator of the router the robot was told to join lists it (one session,
    asked again until it does: each ask waits for the statuses that come)."""
    ca = str(routers.certs / "ca.pem")
    creds = {"open": Credentials(), "auth": Credentials("op", PASSWORDS["op"]),
             "tls": Credentials("op", PASSWORDS["op"], ca=ca)}[kind]
    endpoint = routers.by_kind[kind].endpoint
    session = connect(endpoint, f"nothing answers at {endpoint}", "the router fixture", creds=creds)
    joined = threading.Event()
    # The robot's liveliness token says when to look (history: one already there counts).
    token = session.liveliness().declare_subscriber(
        Keys(robot).alive, lambda sample: joined.set(), history=True
    )
    try:
        deadline = time.monotonic() + LIST_DEADLINE_S
        if not joined.wait(LIST_DEADLINE_S):
            return False
        # Joined: the list asks the router again (its token query can time out on a loaded
        # machine), each ask waiting for the replies and statuses that come.
        while time.monotonic() < deadline:
            if robot in {r.name for r in discover(session, pattern=robot)}:
                return True
        return False
    finally:
        token.undeclare()
        session.close()


@pytest.mark.parametrize("name", list(CASES))
def test_every_combination_works_or_stops_at_start_with_one_line(
    routers: Routers, name: str
) -> None:
    case = CASES[name]
    stderr = routers.directory / f"{uuid.uuid4().hex}.err"
    robot, proc = _start(case, routers, stderr)
    try:
        if case.refusal:
            proc.wait(timeout=120)
            err = stderr.read_text()
            assert proc.returncode != 0
            lines = [x for x in err.splitlines() if x.startswith("darwin up:")]
            assert len(lines) == 1 and case.refusal in lines[0], err
            assert "Traceback" not in err
        else:
            assert _listed(routers, case.router, robot), (
                f"{robot} was never listed through the {case.router} router"
            )
            assert proc.poll() is None
    finally:
        stop_group(proc)
