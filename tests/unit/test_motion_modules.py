"""Head, fall detection and recovery, and the sound player, stepped with synthetic frames."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from config.loader import load_all, load_robot
from robot_daemon.frames import JointFrame
from robot_daemon.motion.setup import build_manager
from robot_daemon.motion.sound import SoundPlayer
from tests.unit.motion_rig import DT, PerfectServos


class Rig(PerfectServos):
    def __init__(self) -> None:
        self.settings = load_all()
        super().__init__(build_manager(load_robot(), self.settings))
        self.accel_y = 512
        self.run(100)  # still, upright: the gyro centre is measured (motion/gyro_centre.py)
        assert self.m("imu").calibrated

    def run(self, ticks: int) -> None:
        for _ in range(ticks):
            f = self.frame()
            # Robot x = the CM-730's accel Y; lying (accel Y off centre) gravity leaves accel Z.
            f.accel_raw = np.array([self.accel_y, 512, 640 if self.accel_y == 512 else 512])
            self.step(f)

    def m(self, name: str):
        return self.manager.module(name)


def test_head_moves_within_limits_at_bounded_speed_and_goes_home() -> None:
    rig = Rig()
    head = rig.m("head")
    head.move(math.radians(60), math.radians(-20))
    rig.run(1)
    assert abs(rig.pos[19]) <= head.limits.speed * DT + 1e-9
    rig.run(200)
    assert head.reached()
    assert math.degrees(rig.pos[19]) == pytest.approx(60)
    assert math.degrees(rig.pos[20]) == pytest.approx(-20)
    with pytest.raises(ValueError, match=r"pan 80\.0° is outside -70°\.\.70°"):
        head.move(math.radians(80), 0.0)
    with pytest.raises(ValueError, match=r"tilt 45\.0°"):
        head.move(0.0, math.radians(45))
    head.home()
    rig.run(200)
    assert (math.degrees(rig.pos[19]), math.degrees(rig.pos[20])) == pytest.approx((0, 10))


def test_head_tracking_turns_toward_the_error_and_stays_in_limits() -> None:
    rig = Rig()
    head = rig.m("head")
    head.home()
    rig.run(100)
    first = head.track(math.radians(10), math.radians(-5))
    assert first[0] > 0 and first[1] < math.radians(10)
    for _ in range(200):
        head.track(math.radians(30), math.radians(30))
        rig.run(1)
    assert head.target == pytest.approx((math.radians(70), math.radians(40)))


def test_a_forward_fall_stops_walking_emits_and_plays_get_up_front() -> None:
    rig = Rig()
    rig.manager.controller = "c1"  # the lease holder's walk: a fall is recovered from
    rig.m("walking").start(0.05, 0, 0)
    rig.run(200)
    assert rig.m("walking").running
    rig.manager.drain_events()
    rig.accel_y = 384  # face down: gravity along −y (1 g)
    rig.run(40)
    assert not rig.m("walking").running
    falls = [d for k, _, d in rig.manager.drain_events() if k == "fall"]
    assert falls == [
        {"state": "fallen_forward", "direction": "forward", "recovering": True, "page": 10}
    ]
    assert rig.m("action").status()["page"] == 10
    assert rig.m("fall").falls == 1
    rig.run(100)
    assert rig.m("fall").falls == 1  # still lying: one fall, not one per tick


def _holders_walk(rig: Rig) -> None:
    rig.manager.controller = "c1"
    rig.m("walking").start(0.0, 0, 0)
    rig.run(5)


def test_a_backward_fall_plays_get_up_back_and_recovery_can_be_disabled() -> None:
    rig = Rig()
    _holders_walk(rig)
    rig.accel_y = 640
    rig.run(31)
    assert rig.m("action").status()["page"] == 11
    rig = Rig()
    _holders_walk(rig)
    rig.m("fall").recover = False
    rig.accel_y = 640
    rig.run(31)
    assert not rig.m("action").playing
    assert rig.m("fall").state == "fallen_backward"
    rig.accel_y = 512
    rig.run(100)
    assert rig.m("fall").state == "upright"


def test_sitting_up_during_the_get_up_page_does_not_restart_it() -> None:
    """Getting up from the back sits up (reads upright for longer than settle_ticks) and rocks
    back again on the way: one fall and one page, played to the end (the MuJoCo plant restarted
    page 11 from step 1 in a loop before); upright again is reported once the page is over."""
    rig = Rig()
    fall, action = rig.m("fall"), rig.m("action")
    _holders_walk(rig)
    rig.accel_y = 640
    rig.run(31)
    assert action.status()["page"] == 11
    rig.accel_y = 512  # sitting up
    rig.run(fall.settle_ticks + 20)
    assert fall.state == "fallen_backward"  # not upright again while the page plays
    rig.accel_y = 640  # leaning back on the hands
    rig.run(40)
    assert action.status()["page"] == 11 and action.status()["step"] > 1
    rig.accel_y = 512
    while action.playing:
        rig.run(1)
    rig.run(fall.settle_ticks)
    falls = [d for k, _, d in rig.manager.drain_events() if k == "fall"]
    assert [d["state"] for d in falls] == ["fallen_backward", "upright"]
    assert fall.falls == 1 and fall.state == "upright"


def test_sound_is_an_event_in_the_simulator_and_a_subprocess_on_the_robot() -> None:
    got: list[tuple[str, str, dict]] = []

    def emit(kind: str, message: str, **data: object) -> None:
        got.append((kind, message, data))

    player = SoundPlayer({"backend": "event"})
    assert player.play(emit, say="Olá", lang="pt")["played"] == "event"
    assert got[-1][0] == "sound" and got[-1][2]["say"] == "Olá"
    with pytest.raises(ValueError, match="file or a phrase"):
        player.play(emit)
    cmd = SoundPlayer({"backend": "command", "say_command": [sys.executable, "-c", "pass"]})
    assert cmd.play(emit, say="hello")["played"] == sys.executable
    missing = SoundPlayer({"backend": "command", "say_command": ["no-such-player-xyz"]})
    with pytest.raises(ValueError, match="not installed"):
        missing.play(emit, say="hello")
    with pytest.raises(ValueError, match="does not exist"):
        cmd.play(emit, file="/nonexistent/a.wav")
    cmd.close()


def test_a_shove_of_an_upright_body_is_not_a_fall() -> None:
    """Pushed hard, an upright body reads accel Y far off centre for longer than the window
    (the MuJoCo plant: 60 N for 0.2 s reads ~225), but gravity is still along its up axis
    (accel Z at 1 g): not a fall, so the direction is decided once it lies."""
    rig = Rig()
    fall = rig.m("fall")
    for tick in range(60):
        f = JointFrame(tick, tick * DT, DT, position=rig.pos.copy())
        f.accel_raw = np.array([225, 512, 640])
        fall.observe(f)
    assert fall.state == "upright" and fall.falls == 0


def test_a_shove_in_the_window_does_not_call_the_side_the_robot_does_not_lie_on() -> None:
    """A strong backward shove reads like a forward fall (accel Y far below centre) while the
    body already tilts back past the Z threshold; on the window alone that was called forward,
    and page 10 would then fold a robot lying on its back. Only a reading of gravity (about 1 g)
    on the window's side calls the fall."""
    rig = Rig()
    fall = rig.m("fall")
    tick = 0

    def feed(reading: list[int], n: int) -> None:
        nonlocal tick
        for _ in range(n):
            f = JointFrame(tick, tick * DT, DT, position=rig.pos.copy())
            f.accel_raw = np.array(reading)
            fall.observe(f)
            tick += 1

    feed([250, 512, 560], 25)  # shoved: 2.1 g, the window's mean reads forward
    assert fall.falls == 0 and fall.state == "upright"
    feed([300, 512, 500], 5)  # striking the floor: 1.7 g
    assert fall.falls == 0
    feed([640, 512, 512], 60)  # lying on its back: 1 g along +Y
    assert fall.falls == 1 and fall.state == "fallen_backward"
