"""The arbiter under abuse, on a real `darwin up`: no client freezes the loop, fools the lease,
widens a command with a payload or hurts the hardware."""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator

import msgpack
import pytest
import zenoh

from clients.robot import Commander, Robot
from schemas import SCHEMA_VERSION
from schemas.errors import (
    LeaseBusyError,
    OutOfRangeError,
    RefusedError,
    RobotUnreachableError,
    UnavailableError,
)
from schemas.keys import Keys
from schemas.messages import Event, Joints
from schemas.session import open_client
from schemas.sim_control import SimControl
from tests.fixtures.system import EventLog, RunningSystem, start_system

WAIT = 20.0
READERS = 8
FLOOD_S = 3.0


def _raw(client: str, **fields: object) -> bytes:
    return msgpack.packb({"v": SCHEMA_VERSION, "client": client, **fields}, use_bin_type=True)


def _ticks(robot: Robot, seconds: float) -> tuple[int, float]:
    """The ticks the daemon made in a window of about ``seconds`` (from the tick numbers it
    publishes), and the window's length."""
    first: Joints = robot.wait_for("joints", timeout=WAIT)
    t0 = time.monotonic()
    time.sleep(seconds)  # a measuring window, not synchronisation
    last: Joints = robot.wait_for("joints", timeout=WAIT)
    return last.tick - first.tick, time.monotonic() - t0


@pytest.fixture
def walking_system() -> Iterator[tuple[RunningSystem, Robot]]:
    with start_system() as system, system.robot_client(name="walker") as robot:
        robot.wait_for("joints", timeout=WAIT)
        robot.acquire()
        robot.walk(x=0.02)
        robot.wait_for("status", lambda s: s.motion.get("walking", {}).get("walking"), WAIT)
        yield system, robot


def test_a_read_flood_while_walking_keeps_the_ticks(walking_system) -> None:
    system, robot = walking_system
    keys = Keys(system.robot)
    expected = 1000.0 / robot.config()["tick_ms"]
    stop, flooding = threading.Event(), threading.Event()
    outcomes: dict[str, int] = {}
    lock = threading.Lock()
    session = open_client(system.endpoint)

    def reader(n: int) -> None:
        payload = _raw(f"reader{n}", id=19, address=36, length=2)  # no lease needed
        while not stop.is_set():
            if not flooding.wait(0.1):
                continue
            for reply in session.get(keys.cmd("registers"), payload=payload, timeout=5):
                if reply.ok is not None:
                    kind = "ok"
                else:
                    raw = reply.err.payload.to_bytes()
                    try:
                        d = msgpack.unpackb(raw)
                    except ValueError:  # not the daemon's: Zenoh's own (b"Timeout", a loaded host)
                        d = {"code": "zenoh: " + raw.decode(errors="replace")}
                    kind = d.get("code", "?") if isinstance(d, dict) else "?"
                with lock:
                    outcomes[kind] = outcomes.get(kind, 0) + 1

    threads = [threading.Thread(target=reader, args=(n,), daemon=True) for n in range(READERS)]
    quiet: list[tuple[int, float]] = []
    flooded: list[tuple[int, float]] = []
    try:
        for t in threads:
            t.start()
        # Windows without and with the flood alternate, for the printed figures.
        for _ in range(3):
            quiet.append(_ticks(robot, FLOOD_S / 2))
            flooding.set()
            flooded.append(_ticks(robot, FLOOD_S / 2))
            flooding.clear()
        flooding.set()
        # halt is never starved by the flood: it is taken first, and stops the walk.
        robot.halt()
        robot.wait_for("status", lambda s: not s.motion.get("walking", {}).get("walking"), WAIT)
    finally:
        stop.set()
        for t in threads:
            t.join(timeout=10)
        session.close()

    def rate(windows: list[tuple[int, float]]) -> float:
        return sum(n for n, _ in windows) / sum(s for _, s in windows)

    print(f"ticks/s: expected {expected:.1f}, quiet {rate(quiet):.1f}, "
          f"flooded {rate(flooded):.1f}; {outcomes}")
    assert outcomes.get("ok", 0) > 0 and "internal" not in outcomes, outcomes
    # The loop went on ticking in every flooded window. How many ticks a second the flood
    # leaves is a figure of the machine's load, not a verdict: it is the benchmark's
    # (benchmarks/arbiter_flood.py, against a clean phase of the same run); that reads wait
    # for their share of the bus, spread over ticks, is tests/unit/test_arbiter_budget.py's.
    assert all(n > 0 for n, _ in flooded), flooded


def test_a_reused_client_id_cannot_command_or_release(robot_system: RunningSystem) -> None:
    with (
        robot_system.robot_client(name="holder") as holder,
        robot_system.robot_client(name="observer") as observer,
    ):
        holder.acquire()
        try:
            public = observer.wait_for("status", lambda s: s.lease is not None, WAIT).lease
            assert public["client"] == holder.client_id and "token" not in public
            impostor = Commander(
                robot_system.endpoint,
                robot_system.robot,
                client_id=public["client"],  # the id everyone can read in status
                session=observer.session,
            )
            with pytest.raises(LeaseBusyError):
                impostor.joint(1, 0.1)
            assert impostor.release()["released"] is False
            with pytest.raises(LeaseBusyError):
                impostor.acquire()
            assert holder.joint("head_pan", 0.1)  # the real holder still commands
        finally:
            holder.release()


def test_a_spoofed_liveliness_token_does_not_keep_a_dead_holder(
    robot_system: RunningSystem,
) -> None:
    """A holder that dies while another session keeps a liveliness token with its id loses the
    lease anyway: only its heartbeat, signed with the secret, keeps the lease."""
    keys = Keys(robot_system.robot)
    victim_id = "victim-spoofed"
    with robot_system.robot_client(name="observer") as observer:
        events = EventLog()
        sub = observer.subscribe("events", events)
        spoof = observer.session.liveliness().declare_token(keys.client(victim_id))
        victim = Robot(
            robot_system.endpoint, robot_system.robot, name="victim", client_id=victim_id
        )
        try:
            victim.wait_for("joints", timeout=WAIT)
            victim.acquire()
            victim.walk(x=0.02)
            events.wait(lambda e: e.kind == "walk" and e.data.get("state") == "started")
        finally:
            victim.close()  # dies: its own token goes, the spoofed one stays
        try:
            ended: Event = events.wait(lambda e: e.kind == "lease" and e.data.get("holder") is None)
            assert ended.data.get("reason") in ("holder silent", "holder vanished")
            events.wait(lambda e: e.kind == "walk" and e.data.get("state") == "stopped")
        finally:
            spoof.undeclare()
            sub.close()


def test_oversized_payloads_are_refused_and_no_tick_waits_for_them(
    robot_system: RunningSystem,
) -> None:
    keys = Keys(robot_system.robot)
    window = 1.0
    with robot_system.robot_client(name="big") as robot:
        with pytest.raises(OutOfRangeError) as info:
            robot.command("lease", op="status", name="n" * 300_000)
        assert info.value.field == "payload" and len(info.value.message) < 200
        big = _raw("big", op="status", name="x" * (16 * 1024 * 1024))

        def skipped() -> int:
            return robot.wait_for("status", timeout=WAIT).loop["skipped"]

        def tick() -> int:
            return robot.wait_for("joints", timeout=WAIT).tick

        quiet = loud = 0
        for _ in range(3):
            # Alternate windows of the same length with and without a 16 MB payload: the
            # machine's own load is in both.
            before = skipped()
            time.sleep(window)  # a measuring window, not synchronisation
            quiet += skipped() - before
            before, first = skipped(), tick()
            replies = list(robot.session.get(keys.cmd("lease"), payload=big, timeout=window))
            assert all(r.ok is None for r in replies)  # refused, or dropped by Zenoh
            assert tick() > first  # the loop went on while the payload came in
            loud += skipped() - before
        assert robot.config()["robot"] == robot_system.robot  # still serving
    # Before the limit one 16 MB payload stalled the loop ~290 ms (~35 deadlines, ~100 here).
    # How many deadlines it costs now is a figure, not a threshold: beside two busy loops the
    # machine's own jitter once made it 7 against 0 in the quiet windows.
    # benchmarks/arbiter_flood.py's "16 MB payloads" phase measures it against a clean one.
    print(f"skipped deadlines in 3 s: quiet {quiet}, with a 16 MB payload a second {loud}")


def test_power_and_id_writes_are_refused_without_the_admin_switch(
    robot_system: RunningSystem,
) -> None:
    with robot_system.robot_client(name="admin?") as robot, robot.control():
        sim = SimControl(robot.session, robot_system.robot)
        with pytest.raises(RefusedError) as info:
            robot.registers(200, 24, data=[0])  # CM-730 DXL_POWER
        assert "--allow-hardware-writes" in info.value.message
        with pytest.raises(RefusedError):
            robot.registers(19, 3, data=[42])  # a servo's ID
        state = sim.call("state")
        assert state["dxl_power"] is True and "19" in state["servos"]
        assert robot.config()["allow_hardware_writes"] is False


def test_a_rate_limited_client_is_told_when_to_retry(robot_system: RunningSystem) -> None:
    keys = Keys(robot_system.robot)
    with robot_system.robot_client(name="hasty") as robot:
        payload = _raw("hasty-raw", id=19, address=36, length=2)
        # 40 reads at once from one client (not waiting for each reply).
        pending = [
            robot.session.get(keys.cmd("registers"), payload=payload, timeout=10)
            for _ in range(40)
        ]
        codes = [
            msgpack.unpackb(reply.err.payload.to_bytes())
            for handler in pending
            for reply in handler
            if reply.err is not None
        ]
        limited = [d for d in codes if d.get("code") == "rate_limited"]
        assert limited, codes[:3]
        assert limited[0]["retry_after"] >= 0 and "retry in" in limited[0]["message"]
        # The Robot client waits as told instead of failing with rate_limited (a busy machine may
        # still make the emulator miss a reply: that is `unavailable`, from the bus).
        read = 0
        for _ in range(10):
            with contextlib.suppress(UnavailableError):
                read += len(robot.registers(19, 36, 2)["data"]) == 2
        assert read > 0


def test_a_missing_daemon_is_a_client_error(robot_system: RunningSystem) -> None:
    with Robot(robot_system.endpoint, "nobody-here", timeout=0.5) as robot:
        with pytest.raises(RobotUnreachableError) as info:
            robot.config()
        assert "nobody answers" in str(info.value)


def test_zenoh_session_survives_a_dropped_message(robot_system: RunningSystem) -> None:
    with robot_system.robot_client(name="after") as robot:
        session: zenoh.Session = robot.session
        big = _raw("after", op="status", name="y" * (12 * 1024 * 1024))
        list(session.get(Keys(robot_system.robot).cmd("lease"), payload=big, timeout=0.5))
        assert robot.config()["robot"] == robot_system.robot


def test_the_secret_stays_with_the_client_however_it_takes_the_lease(
    robot_system: RunningSystem,
) -> None:
    """The TUI sends `lease` through ``command``; the client keeps and renews the secret the
    same way as with ``acquire``."""
    with robot_system.robot_client(name="tui-like") as robot:
        applied = robot.command("lease", op="acquire")
        assert "token" not in applied and robot.holds_lease
        try:
            time.sleep(2.0)  # longer than the heartbeat timeout: only renewals keep the lease
            assert robot.joint("head_pan", 0.05)["name"] == "head_pan"
        finally:
            robot.command("lease", op="release")
        assert not robot.holds_lease
