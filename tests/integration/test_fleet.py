"""A fleet on loopback, all real: `darwin router`, two simulated robots joined to it
(`darwin up --router … --robot op1` / `op2`, each its own emulator, world and daemon), and
clients that know only the router's endpoint."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import threading
import time
import typing
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import zenoh

from clients.fleet import discover
from clients.recording import Replayer, read_recording
from clients.robot import Robot
from schemas.keys import every_robot, robot_of
from schemas.messages import NetworkInfo
from schemas.session import free_tcp_port, open_client
from tests.fixtures.fleet import RunningRouter, start_router
from tests.fixtures.system import RunningSystem, run_darwin, start_system

HEAD_PAN = 19


@dataclass
class Fleet:
    router: RunningRouter
    robots: dict[str, RunningSystem]

    @property
    def endpoint(self) -> str:
        return self.router.endpoint


def names() -> tuple[str, str]:
    """Robot names unique to this run (several runs may share the machine)."""
    tag = uuid.uuid4().hex[:6]
    return f"op1-{tag}", f"op2-{tag}"


@pytest.fixture(scope="module")
def fleet() -> Iterator[Fleet]:
    a, b = names()
    with (
        start_router() as router,
        start_system(router=router.endpoint, robot=a, gateway=False) as op1,
        start_system(router=router.endpoint, robot=b, gateway=False) as op2,
    ):
        yield Fleet(router, {a: op1, b: op2})


def test_robots_joined_to_a_router_print_the_router_as_their_endpoint(fleet: Fleet) -> None:
    assert fleet.router.lines[0] == f"router: {fleet.endpoint}"
    for system in fleet.robots.values():
        assert system.endpoint == fleet.endpoint  # `zenoh: …` is where clients connect


def test_darwin_list_shows_every_live_robot(fleet: Fleet) -> None:
    out = run_darwin("list", "--connect", fleet.endpoint, "--json")
    assert out.returncode == 0, out.stderr
    records = {r["name"]: r for r in json.loads(out.stdout) if r["name"] in fleet.robots}
    assert set(records) == set(fleet.robots)
    for r in records.values():
        assert r["endpoint"] == fleet.endpoint
        assert r["state"] in ("running", "degraded")  # a loaded machine may starve a read
        assert r["lease_holder"] is None
        assert r["battery"] > 0
        assert r["alarms"] == []
        assert r["loop_hz"] > 0
    lines = run_darwin("list", "--connect", fleet.endpoint).stdout.splitlines()
    for name in fleet.robots:
        assert any(line.startswith(f"{name}: {fleet.endpoint}") for line in lines), lines


def test_one_observer_of_every_robot_gets_both(fleet: Fleet) -> None:
    seen: set[str] = set()
    cond = threading.Condition()

    def on_joints(sample: zenoh.Sample) -> None:
        with cond:
            seen.add(robot_of(str(sample.key_expr)))
            cond.notify_all()

    with contextlib.closing(open_client(fleet.endpoint)) as session:
        sub = session.declare_subscriber(every_robot().joints, on_joints)
        with cond:
            assert cond.wait_for(lambda: set(fleet.robots) <= seen, 15), seen
        sub.undeclare()


def test_a_command_to_one_robot_moves_it_and_not_the_other(fleet: Fleet) -> None:
    first, second = fleet.robots
    with (
        Robot(fleet.endpoint, first, name="watcher") as one,
        Robot(fleet.endpoint, second, name="driver") as two,
    ):
        goal_before = one.wait_for("joints").goal[HEAD_PAN - 1]
        start = two.wait_for("joints").position[HEAD_PAN - 1]
        target = 0.4 if abs(start - 0.4) > 0.1 else -0.3
        with two.control():
            two.joint("head_pan", target)
            two.wait_for(
                "joints", lambda m: abs(m.position[HEAD_PAN - 1] - target) < 0.02, timeout=15
            )
            by_name = {r.name: r for r in discover(two.session) if r.name in fleet.robots}
            assert by_name[second].lease_holder == "driver"
            assert by_name[first].lease_holder is None
        # The other robot's goal never changed: the command reached only its robot.
        assert one.wait_for("joints").goal[HEAD_PAN - 1] == pytest.approx(goal_before)


def test_robot_discover_returns_the_records_darwin_list_prints(fleet: Fleet) -> None:
    keys = ("name", "endpoint", "state", "alarms")

    def discovered() -> dict[str, dict[str, object]]:
        found = {r.name: r.to_dict() for r in Robot.discover(fleet.endpoint)}
        return {n: {k: found[n][k] for k in keys} for n in fleet.robots if n in found}

    # A robot's state may change between two reads (a loaded machine turns a servo's missed
    # replies into "degraded" for a moment): the two are compared when the records read just
    # before and just after `darwin list` agree, so the list read the same robot.
    for _ in range(5):
        before = discovered()
        assert set(before) == set(fleet.robots)
        out = run_darwin("list", "--connect", fleet.endpoint, "--json").stdout
        listed = {r["name"]: {k: r[k] for k in keys} for r in json.loads(out)}
        if discovered() == before:
            break
    else:
        raise AssertionError(f"the robots' records never held still: {before}")
    assert {n: listed.get(n) for n in fleet.robots} == before


def _daemon_pid(system: RunningSystem) -> int:
    """The `darwin daemon` child of a `darwin up`."""
    children = Path(f"/proc/{system.process.pid}/task/{system.process.pid}/children")
    for pid in children.read_text().split():
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
        if b"daemon" in cmdline:
            return int(pid)
    raise AssertionError(f"no daemon child of darwin up ({system.process.pid})")


def test_a_frozen_robot_leaves_the_list_within_its_link_lease(fleet: Fleet) -> None:
    name = f"op3-{uuid.uuid4().hex[:6]}"
    with start_system(router=fleet.endpoint, robot=name, gateway=False) as op3:
        with contextlib.closing(open_client(fleet.endpoint)) as session:
            assert name in {r.name for r in discover(session)}
            gone = threading.Event()

            def on_token(sample: zenoh.Sample) -> None:
                mine = robot_of(str(sample.key_expr)) == name
                if mine and sample.kind == zenoh.SampleKind.DELETE:
                    gone.set()

            sub = session.liveliness().declare_subscriber(every_robot().alive, on_token)
            pid = _daemon_pid(op3)
            # A frozen daemon keeps its socket open but says nothing: only the link lease
            # (3 s shipped) ends its token, as a cut cable would.
            os.kill(pid, signal.SIGSTOP)
            frozen_at = time.monotonic()
            try:
                assert gone.wait(30), "the frozen robot's alive token never went"
                took = time.monotonic() - frozen_at
                assert name not in {r.name for r in discover(session, timeout=0.5)}
                listed = run_darwin("list", "--connect", fleet.endpoint, "--json").stdout
                assert name not in {r["name"] for r in json.loads(listed)}
                print(f"token gone {took:.2f} s after the daemon froze (link lease 3 s)")
            finally:
                os.kill(pid, signal.SIGCONT)
                sub.undeclare()
        # The others were never affected.
        with contextlib.closing(open_client(fleet.endpoint)) as session:
            assert set(fleet.robots) <= {r.name for r in discover(session)}


@pytest.mark.parametrize("which", ["named", "every"])
def test_the_recorder_writes_several_robots_into_one_file(
    fleet: Fleet, tmp_path: Path, which: str
) -> None:
    a, b = fleet.robots
    chosen = ["--robot", a, "--robot", b] if which == "named" else ["--robot", "*"]
    out = tmp_path / "fleet.mcap"
    done = run_darwin(
        "record", "-o", str(out), "--connect", fleet.endpoint, *chosen,
        "--topics", "joints", "status", "--duration", "2",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    rec = read_recording(out)
    assert {a, b} <= set(rec.robots)
    for name in (a, b):
        mine = rec.only(name)
        assert mine.robot == name
        joints = list(mine.decoded("joints"))
        assert joints and all(len(j.position) == 20 for j in joints)
        assert any(s.robot == name for s in mine.decoded("status"))
    # Replay keeps working: it plays one robot of the file, chosen by name.
    refused = run_darwin("replay", str(out), "--connect", fleet.endpoint)
    assert refused.returncode == 2 and "--source" in refused.stderr
    replay_name = f"{b}-again"
    with contextlib.closing(open_client(fleet.endpoint)) as session:
        player = Replayer(rec.only(b), session, replay_name, loop=True)
        player.start()
        try:
            with Robot(fleet.endpoint, replay_name, name="viewer") as viewer:
                assert len(viewer.wait_for("joints", timeout=10).position) == 20
        finally:
            player.stop()


def test_status_says_where_the_robot_is_reached(fleet: Fleet) -> None:
    name = next(iter(fleet.robots))
    with Robot(fleet.endpoint, name, name="network") as robot:
        status = robot.wait_for("status")
    assert set(status.network) == set(typing.get_type_hints(NetworkInfo))
    assert status.network == {"endpoint": fleet.endpoint, "router": fleet.endpoint, "listen": []}


def test_router_and_fleet_failures_are_one_line(fleet: Fleet) -> None:
    busy = run_darwin("router", "--listen", fleet.endpoint)
    assert busy.returncode == 1
    assert busy.stderr.strip().count("\n") == 0 and "already in use" in busy.stderr
    bad = run_darwin("router", "--listen", "localhost:7447")
    assert bad.returncode == 1 and "not a Zenoh locator" in bad.stderr
    nobody = f"tcp/127.0.0.1:{free_tcp_port()}"
    alone = run_darwin("up", "--router", nobody, "--robot", "lonely", "--no-gateway")
    assert alone.returncode == 1
    assert f"cannot reach the router at {nobody}" in alone.stderr
    assert "Traceback" not in alone.stderr
    listed = run_darwin("list", "--connect", nobody)
    assert listed.returncode == 1 and "nothing answers" in listed.stderr
