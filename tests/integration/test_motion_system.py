"""Motion through the whole system: daemon + emulator over a pseudo-terminal, commands over
Zenoh. Pages reach their poses, walking swings the legs alternately at the configured period
and stops at the end of a step, choreographies report every item in order and stop on request,
and losing the lease mid-walk stops the robot."""

from __future__ import annotations

import math
import queue
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from clients.robot import Robot
from config.loader import load_all, load_robot
from robot_daemon.motion.action.library import load_library
from robot_daemon.motion.walking.gait import foot_heights
from schemas.messages import Event, Joints
from tests.fixtures.system import RunningSystem, start_system

WAIT = 30.0  # generous deadlines: CI machines are slow, the daemon is real time


class Events:
    """Every event from the moment of creation; ``wait`` blocks until one matches."""

    def __init__(self, robot: Robot) -> None:
        self.seen: list[Event] = []
        self._cond = threading.Condition()
        self._sub = robot.subscribe("events", self._on)

    def _on(self, msg: Any) -> None:
        with self._cond:
            self.seen.append(msg)
            self._cond.notify_all()

    def wait(self, pred: Callable[[Event], bool], timeout: float = WAIT) -> Event:
        with self._cond:
            ok = self._cond.wait_for(lambda: any(pred(e) for e in self.seen), timeout)
            assert ok, f"no matching event within {timeout} s; saw {[e.message for e in self.seen]}"
            return next(e for e in self.seen if pred(e))

    def close(self) -> None:
        self._sub.close()


@pytest.fixture
def robot(robot_system: RunningSystem) -> Iterator[Robot]:
    with robot_system.robot_client(name="motion-test") as r:
        r.wait_for("joints", timeout=WAIT)
        r.acquire()
        try:
            yield r
        finally:
            r.command("halt")
            r.release()


def _kind(kind: str, **data: Any) -> Callable[[Event], bool]:
    return lambda e: e.kind == kind and all(e.data.get(k) == v for k, v in data.items())


def _at(m: Joints, ids: list[int], want: dict[int, float]) -> bool:
    return all(abs(m.position[ids.index(j)] - v) < math.radians(2) for j, v in want.items())


def test_sit_down_then_stand_up_reach_the_pages_poses(robot: Robot) -> None:
    lib = load_library()
    ids = list(load_robot().ids)
    for name in ("sit down", "stand up"):
        events = Events(robot)
        applied = robot.action(name)
        page = lib.page(name)
        assert applied["page"] == page.number
        events.wait(_kind("action", page=page.number, state="finished"))
        events.close()
        last = page.steps[-1]
        want = {j: (last.words[j] - 2048) * 2 * math.pi / 4096 for j in ids if last.driven(j)}
        # The emulated servos follow their goals at a bounded speed: wait until they are there.
        try:
            robot.wait_for("joints", lambda m, want=want: _at(m, ids, want), timeout=WAIT)
        except Exception:
            m = robot.wait_for("joints", timeout=WAIT)
            raise AssertionError(
                [
                    (j, round(math.degrees(m.position[ids.index(j)] - v), 1))
                    for j, v in want.items()
                ],
                [e.message for e in events.seen],
            ) from None


def test_walking_alternates_legs_at_the_period_and_stops_within_a_step(robot: Robot) -> None:
    params = load_all()["walking"]
    robot_cfg = load_robot()
    ids = list(robot_cfg.ids)
    period_ticks = round(params["period_time"] / 8.0)
    period_s = params["period_time"] / 1000.0
    events = Events(robot)
    got: queue.Queue[Joints] = queue.Queue()
    sub = robot.subscribe("joints", got.put)
    # Gyro feedback answers the emulated IMU's noise by moving the feet a few mm, which would
    # blur the lift-off ticks: the gait's own timing is measured with it off.
    robot.command("walk_params", set={"balance_enable": False})
    try:
        robot.walk(x=0.08)
        events.wait(_kind("walk", state="started"))
        # Let the blend into the stance pass, then record a few cycles.
        robot.wait_for("status", lambda s: s.motion.get("walking", {}).get("steps", 0) >= 3, WAIT)
        while not got.empty():
            got.get_nowait()
        # Four and a half periods of the clock, not a count of ticks: a late tick on a busy
        # machine is followed by a short one (the loop does not burst to catch up), so 4 periods
        # of ticks can be less than 4 periods of gait time.
        frames: list[Joints] = [got.get(timeout=WAIT)]
        while len(frames) < period_ticks or frames[-1].stamp - frames[0].stamp < 4.5 * period_s:
            frames.append(got.get(timeout=WAIT))
        robot.walk_stop()
        stopped = events.wait(_kind("walk", state="stopped"))
    finally:
        robot.command("walk_params", set={"balance_enable": params["balance_enable"]})
    sub.close()
    events.close()

    lean = math.radians(params["hip_pitch_offset"])
    heights = []
    for m in frames:
        # The swing pattern from the goals the daemon sent (the emulated servos follow them
        # with a lag that depends on the machine's load); the limits on the present positions.
        goals = {j: m.goal[ids.index(j)] for j in range(7, 19)}
        heights.append(foot_heights(goals, lean))
        for j in range(7, 19):
            assert robot_cfg.by_id[j].within(m.position[ids.index(j)])
            assert robot_cfg.by_id[j].within(m.goal[ids.index(j)])
    h = np.array(heights)
    # Gait time follows the clock, so the period is in seconds (the sampling stamps), whatever
    # number of ticks a busy machine fits into it.
    stamps = np.array([m.stamp for m in frames])
    lifted_r, lifted_l = h[:, 0] > 0.015, h[:, 1] > 0.015
    assert not np.any(lifted_r & lifted_l)
    starts_l = [stamps[i] for i in range(1, len(h)) if lifted_l[i] and not lifted_l[i - 1]]
    starts_r = [stamps[i] for i in range(1, len(h)) if lifted_r[i] and not lifted_r[i - 1]]
    assert len(starts_l) >= 3 and len(starts_r) >= 3, (
        f"{len(frames)} samples over {stamps[-1] - stamps[0]:.2f} s (ticks "
        f"{frames[0].tick}..{frames[-1].tick}); lift-offs left {starts_l}, right {starts_r}; "
        f"highest feet {h.max(axis=0)}; events {[e.message for e in events.seen]}"
    )
    # Each foot lifts once per period, the two half a period apart, to within what the samples
    # resolve: a lift-off is seen at the first sample after it, so each difference of two is off
    # by at most the widest gap between samples (a late tick on a busy machine, a dropped one).
    slack = max(3 * 0.008, 2 * float(np.max(np.diff(stamps))))
    assert all(abs(d - period_s) <= slack for d in np.diff(starts_l)), (starts_l, starts_r)
    assert all(abs(d - period_s) <= slack for d in np.diff(starts_r))
    assert abs(abs(starts_r[0] - starts_l[0]) % period_s - period_s / 2) <= slack
    # Stop: the current step and at most one more to bring the feet together.
    assert stopped.data["steps"] >= 3


def test_stop_ends_walking_at_the_end_of_the_next_step(robot: Robot) -> None:
    events = Events(robot)
    robot.walk(x=0.05)
    robot.wait_for("status", lambda s: s.motion.get("walking", {}).get("steps", 0) >= 2, WAIT)
    applied = robot.walk_stop()
    assert applied["stopping"] is True
    stopped = events.wait(_kind("walk", state="stopped"))
    events.close()
    # The current step ends, and at most one more brings the feet together.
    assert stopped.data["steps"] - applied["steps"] <= 2
    # The legs are handed back (holding the pose) on the tick after the last step ends.
    robot.wait_for(
        "status",
        lambda s: (
            s.motion["walking"]["walking"] is False and "walking" not in s.motion["owners"].values()
        ),
        WAIT,
    )


def test_choreography_reports_each_item_in_order(robot: Robot) -> None:
    events = Events(robot)
    items = [
        {"behaviour": "look left"},
        {"kind": "pause", "duration": 0.3},
        {"behaviour": "yes"},
    ]
    run = robot.choreography(items)["run"]
    events.wait(_kind("choreography", run=run, state="finished"))
    events.close()
    seq = [
        (e.data["state"], e.data.get("index"))
        for e in events.seen
        if e.kind == "choreography" and e.data.get("run") == run
    ]
    assert seq == [
        ("started", None),
        ("item_started", 0),
        ("item_finished", 0),
        ("item_started", 1),
        ("item_finished", 1),
        ("item_started", 2),
        ("item_finished", 2),
        ("finished", 3),  # index: how many items were played
    ]


def test_choreography_stop_mid_list_skips_the_rest(robot: Robot) -> None:
    events = Events(robot)
    run = robot.choreography(
        [{"kind": "pause", "duration": 60}, {"behaviour": "wow"}, {"behaviour": "bow"}]
    )["run"]
    events.wait(_kind("choreography", run=run, state="item_started", index=0))
    robot.choreography_stop()
    events.wait(_kind("choreography", run=run, state="stopped"))
    events.close()
    started = [
        e.data["index"]
        for e in events.seen
        if e.kind == "choreography"
        and e.data.get("run") == run
        and e.data["state"] == "item_started"
    ]
    assert started == [0]


def test_bad_motion_commands_are_refused_naming_the_field(robot: Robot) -> None:
    from schemas.errors import CommandError

    with pytest.raises(CommandError) as err:
        robot.walk(x=5.0)
    assert err.value.field == "x"
    with pytest.raises(CommandError) as err:
        robot.action(250)
    assert err.value.field == "page"
    with pytest.raises(CommandError) as err:
        robot.head(pan=2.0, tilt=0.0)
    assert err.value.field == "pan"
    with pytest.raises(CommandError) as err:
        robot.choreography([{"behaviour": 9999}])
    assert err.value.field == "behaviour"
    table = robot.command("behaviours")
    assert table["types"]["1"] == "action"
    assert any(b["id"] == 301 and b["say"] == "Thank you" for b in table["behaviours"])


def test_losing_the_lease_mid_walk_stops_the_robot(robot_system: RunningSystem) -> None:
    with robot_system.robot_client(name="observer") as observer:
        events = Events(observer)
        walker = robot_system.robot_client(name="walker")
        try:
            walker.wait_for("joints", timeout=WAIT)
            walker.acquire()
            walker.walk(x=0.05)
            events.wait(_kind("walk", state="started"))
        finally:
            walker.close()  # the holder vanishes: its liveliness token goes with it
        events.wait(_kind("walk", state="stopped"))
        observer.wait_for(
            "status", lambda s: not s.motion.get("walking", {}).get("walking", True), WAIT
        )
        events.close()


def test_a_released_lease_stops_the_walk_within_a_step(robot_system: RunningSystem) -> None:
    with robot_system.robot_client(name="releaser") as walker:
        walker.wait_for("joints", timeout=WAIT)
        events = Events(walker)
        with walker.control():
            walker.walk(x=0.05)
            events.wait(_kind("walk", state="started"))
            walking = walker.wait_for(
                "status", lambda s: s.motion.get("walking", {}).get("steps", 0) >= 2, WAIT
            )
        # Leaving the block released the lease: nobody controls the walk, so it ends. The lease
        # change publishes a status on the release's own tick: the count the stop starts from.
        released = walker.wait_for("status", lambda s: s.lease is None, WAIT, fresh=False)
        steps = released.motion["walking"]["steps"]
        assert steps >= walking.motion["walking"]["steps"]
        stopped = events.wait(_kind("walk", state="stopped"))
        events.close()
        assert stopped.data["steps"] - steps <= 2
        walker.wait_for(
            "status", lambda s: not s.motion.get("walking", {}).get("walking", True), WAIT
        )


def test_the_idle_timeout_ends_a_walk_nobody_commands(tmp_path: Path) -> None:
    config = tmp_path / "idle.toml"
    config.write_text("[daemon.lease]\nidle_timeout = 1.5\n")
    with (
        start_system(gateway=False, extra_args=["--config", str(config)]) as system,
        system.robot_client(name="idler") as robot,
    ):
        robot.wait_for("joints", timeout=WAIT)
        events = Events(robot)
        robot.acquire()
        robot.walk(x=0.05)
        # No command after this one: walking on its own is idle for the lease.
        lost = events.wait(
            lambda e: e.kind == "lease" and str(e.data.get("reason", "")).startswith("idle")
        )
        stopped = events.wait(_kind("walk", state="stopped"))
        assert stopped.seq > lost.seq
        events.close()
