"""`darwin up` stops every child it started when it gets SIGTERM or Ctrl-C (SIGINT), leaves
none behind when it is killed outright, and survives the crash of an adapter (the gateway)."""

from __future__ import annotations

import os
import select
import signal
import time

import pytest

from tests.fixtures.system import start_system


def group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_up_leaves_no_child_behind(sig: signal.Signals) -> None:
    with start_system(gateway=False) as system:
        with system.robot_client() as robot:
            assert robot.wait_for("status", timeout=10).state in ("running", "degraded")
        pgid = system.process.pid  # `darwin up` leads its own process group
        os.kill(system.process.pid, sig)  # only `darwin up` itself, not the group
        assert system.process.wait(timeout=30) == 0
        deadline = time.monotonic() + 20
        while group_alive(pgid) and time.monotonic() < deadline:
            time.sleep(0.1)  # children exit on their own; polling their group is all there is
        assert not group_alive(pgid), "a child of `darwin up` outlived it"


def _stat(pid: int) -> tuple[str, int] | None:
    """(state, parent pid) of a process from /proc, None once it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            text = f.read()
    except (FileNotFoundError, ProcessLookupError):
        return None
    fields = text.rsplit(")", 1)[1].split()  # after "pid (comm)": state ppid …
    return fields[0], int(fields[1])


def descendants(root: int) -> dict[int, str]:
    """Every live process below ``root`` → its command line, from a /proc scan."""
    parents: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit() and (st := _stat(int(entry))) is not None and st[0] != "Z":
            parents[int(entry)] = st[1]
    found: dict[int, str] = {}
    frontier = [root]
    while frontier:
        parent = frontier.pop()
        for pid, ppid in parents.items():
            if ppid == parent and pid not in found:
                try:
                    with open(f"/proc/{pid}/cmdline", "rb") as f:
                        found[pid] = f.read().replace(b"\0", b" ").decode(errors="replace")
                except FileNotFoundError:
                    continue
                frontier.append(pid)
    return found


def wait_gone(pids: list[int], timeout: float) -> list[int]:
    """Wait (on pidfds, no polling) until every pid has ended; returns those still running."""
    fds = {}
    for pid in pids:
        try:
            fds[pid] = os.pidfd_open(pid)
        except ProcessLookupError:
            continue
    deadline = time.monotonic() + timeout
    try:
        while fds and (remaining := deadline - time.monotonic()) > 0:
            ready, _, _ = select.select(list(fds.values()), [], [], remaining)
            for pid in [p for p, fd in fds.items() if fd in ready]:
                os.close(fds.pop(pid))
        return [p for p in fds if (st := _stat(p)) is not None and st[0] != "Z"]
    finally:
        for fd in fds.values():
            os.close(fd)


def test_sigkill_of_up_leaves_no_process_behind() -> None:
    with start_system() as system:
        with system.robot_client() as robot:
            assert robot.wait_for("status", timeout=10).state in ("running", "degraded")
        below = descendants(system.process.pid)
        # The daemon, the emulator it started and the gateway: three generations in two.
        assert any(" daemon " in c for c in below.values()), below
        assert any(" sim " in c for c in below.values()), below
        assert any(" gateway " in c for c in below.values()), below
        system.process.kill()  # no chance to clean up
        system.process.wait(timeout=10)
        left = wait_gone(list(below), timeout=30)
        assert not left, {p: below[p] for p in left}


def test_a_crashed_gateway_leaves_the_robot_serving() -> None:
    with start_system() as system, system.robot_client(name="survivor") as robot:
        robot.wait_for("status", timeout=10)
        gateway = [p for p, c in descendants(system.process.pid).items() if " gateway " in c]
        assert len(gateway) == 1
        os.kill(gateway[0], signal.SIGKILL)
        assert not wait_gone(gateway, timeout=10)
        # The daemon keeps serving: statuses keep coming, commands are answered.
        for _ in range(30):
            status = robot.wait_for("status", timeout=10)
        assert status.state in ("running", "degraded")
        with robot.control():
            robot.joint("head_pan", 0.1)
        assert system.alive
        system.wait_line(lambda line: "gateway exited" in line and "keeps running" in line)
        # … and the adapter is started again.
        restarted: list[int] = []
        for _ in range(300):
            robot.wait_for("status", timeout=10)
            restarted = [
                p for p, c in descendants(system.process.pid).items() if " gateway " in c
            ]
            if restarted:
                break
        assert restarted and restarted != gateway


def test_first_run_on_the_emulator_has_the_simulated_camera() -> None:
    with (
        start_system(camera=None, gateway=False) as system,
        system.robot_client(name="newcomer") as robot,
    ):
        assert robot.wait_for("status", timeout=10).camera["source"] == "sim"
        img = robot.image(timeout=15)
        assert img.shape == (240, 320, 3)


def test_sigkill_of_the_daemon_takes_its_emulator_with_it() -> None:
    with start_system(gateway=False) as system:
        with system.robot_client() as robot:
            robot.wait_for("status", timeout=10)
        below = descendants(system.process.pid)
        daemon = [p for p, c in below.items() if " daemon " in c]
        sim = [p for p, c in below.items() if " sim " in c]
        assert len(daemon) == 1 and len(sim) == 1, below
        os.kill(daemon[0], signal.SIGKILL)
        assert not wait_gone(sim, timeout=30), "the emulator outlived its daemon"
        # Without its daemon there is no robot: `darwin up` stops and says so.
        assert system.process.wait(timeout=30) == 1
        system.wait_line(lambda line: "daemon exited" in line)  # its output read to the end
