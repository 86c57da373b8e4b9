"""The learning contract (schemas/policy.py), the gravity filter and the policy module's rules,
without Zenoh: a real MotionManager with the shipped robot config, frames made by hand."""

from __future__ import annotations

import math

import msgpack
import numpy as np
import pytest

from config.loader import load_all, load_robot
from robot_daemon.frames import JointFrame
from robot_daemon.motion.attitude import GravityFilter
from robot_daemon.motion.manager import MotionManager
from robot_daemon.motion.policy import PolicyModule, PolicySettings
from schemas import SCHEMA_VERSION
from schemas.errors import ProtocolError
from schemas.joints import JOINT_IDS, JOINT_NAMES
from schemas.keys import Keys
from schemas.messages import encode
from schemas.policy import (
    DEFAULT_POSE,
    OBSERVATION_SIZE,
    PolicyAction,
    PolicyApplied,
    PolicyObservation,
    PolicyStatus,
)
from schemas.units import GRAVITY

DT = 0.008
KEY = b"k" * 16


def test_joint_names_and_default_pose_match_the_robot_config() -> None:
    robot = load_robot()
    assert tuple(robot.ids) == JOINT_IDS and tuple(robot.names) == JOINT_NAMES
    for jid, rad in zip(JOINT_IDS, DEFAULT_POSE, strict=True):
        assert robot.by_id[jid].within(rad), robot.by_id[jid].name
    assert Keys("op1").policy("action") == "darwin/op1/policy/action"
    with pytest.raises(ValueError, match="unknown policy topic"):
        Keys("op1").policy("actions")


def _obs(**over: object) -> PolicyObservation:
    d = {
        "joint_pos": [0.0] * 20, "joint_vel": [0.0] * 20, "gyro": [0.0] * 3,
        "gravity": [0.0, 0.0, -1.0], "last_action": [0.0] * 20, "command": [0.0] * 3,
    }  # fmt: skip
    d.update(over)
    return PolicyObservation(**d)  # type: ignore[arg-type]


def test_observation_round_trips_and_flattens_in_the_documented_layout() -> None:
    obs = _obs(gyro=[1.0, 2.0, 3.0], tick=7)
    back = PolicyObservation.parse(encode(obs))
    assert back == obs and len(back.vector()) == OBSERVATION_SIZE == 69
    assert back.vector()[:3] == [1.0, 2.0, 3.0]


def _payload(**d: object) -> bytes:
    return msgpack.packb({"v": SCHEMA_VERSION, "type": "policy_action", **d}, use_bin_type=True)


@pytest.mark.parametrize(
    ("payload", "words"),
    [
        (_payload(client="c", seq=1, action=[0.0] * 19), "action must be a list of 20"),
        (_payload(client="c", seq=1, action=[0.0] * 19 + [math.nan]), "action[19]"),
        (_payload(client="c", seq=1, action=[0.0] * 20, speed=3), "unknown field 'speed'"),
        (_payload(client="c", action=[0.0] * 20), "lacks the field 'seq'"),
        (_payload(client="c", seq=-1, action=[0.0] * 20), "seq must be a non-negative"),
        (_payload(client="c", seq=1, action=["a"] * 20), "action[0] must be a number"),
        (b"\xc1", "not valid msgpack"),
        (b"\x00" * 5000, "over the limit"),
        (msgpack.packb({"v": 99, "type": "policy_action"}), "schema version"),
    ],
)
def test_bad_actions_are_refused_naming_what_is_wrong(payload: bytes, words: str) -> None:
    with pytest.raises(ProtocolError, match=None) as exc:
        PolicyAction.parse(payload)
    assert words in str(exc.value)


def test_a_signed_action_verifies_only_with_its_key_and_body() -> None:
    a = PolicyAction.signed("c", KEY, 3, [0.1] * 20, obs_tick=9)
    back = PolicyAction.parse(encode(a))
    assert back.verify(KEY) and not back.verify(b"x" * 16)
    back.action[0] = 0.2
    assert not back.verify(KEY)


def test_gravity_filter_follows_the_accelerometer_and_integrates_the_gyro() -> None:
    f = GravityFilter(tau=0.5)
    f.update((0, 0, 0), (0, 0, GRAVITY), DT)
    assert f.g == pytest.approx([0, 0, -1])
    # Pitch at 1 rad/s for 0.3 s, the accelerometer saying nothing useful (free fall): the gyro
    # alone turns the estimate by 0.3 rad about y.
    for _ in range(int(0.3 / DT)):
        f.update((0.0, 1.0, 0.0), (0.0, 0.0, 0.0), DT)
    assert math.acos(f.upright) == pytest.approx(0.3, abs=0.01)
    # Lying on its back at rest: the accelerometer pulls it there within a few tau.
    for _ in range(int(3.0 / DT)):
        f.update((0, 0, 0), (-GRAVITY, 0.0, 0.0), DT)
    assert f.g == pytest.approx([1.0, 0.0, 0.0], abs=0.01) and f.upright < 0.85


class Rig:
    """A manager with only the policy module, frames at the default pose."""

    def __init__(self, **settings: object) -> None:
        self.robot = load_robot()
        self.manager = MotionManager(self.robot)
        self.policy = PolicyModule(PolicySettings(**settings), clock=lambda: self.tick * DT)  # type: ignore[arg-type]
        self.manager.add(self.policy)
        self.sent: list[tuple[str, object]] = []
        self.policy.sink = lambda topic, msg: self.sent.append((topic, msg))
        self.alarm = ""
        self.policy.health = lambda: self.alarm
        self.tick = 0
        self.pos = np.zeros(21)
        for jid, rad in zip(JOINT_IDS, DEFAULT_POSE, strict=True):
            self.pos[jid] = rad
        self.accel = np.array([0.0, 0.0, GRAVITY])

    def step(self, n: int = 1) -> dict[int, float]:
        goals: dict[int, float] = {}
        for _ in range(n):
            self.tick += 1
            f = JointFrame(self.tick, self.tick * DT, DT, position=self.pos.copy())
            f.online[:] = True
            f.torque_enabled[:] = True
            f.accel = self.accel.copy()
            goals = self.manager.step(f).goal
            for j, g in goals.items():
                self.pos[j] = g
        return goals

    def start(self, **kw: object) -> bytes:
        self.step()
        args = {"rate_hz": 50.0, "mode": "offset", "scale": 0.3, **kw}
        return self.policy.start("me", **args)  # type: ignore[arg-type]

    def applied(self) -> list[PolicyApplied]:
        return [m for t, m in self.sent if t == "applied"]  # type: ignore[misc]


def test_actions_are_clipped_to_limits_and_the_delta_cap_and_answered() -> None:
    rig = Rig(max_delta=0.1)
    key = rig.start()
    far = [1.0] * 20  # 0.3 rad from the default pose on every joint, more than max_delta
    assert rig.policy.offer(PolicyAction.signed("me", key, 1, far)) == ""
    goals = rig.step()
    (ans,) = rig.applied()
    assert ans.seq == 1 and any("max_delta" in c for c in ans.clipped)
    moved = np.array([goals[j] for j in JOINT_IDS]) - np.array(DEFAULT_POSE)
    assert np.abs(moved).max() == pytest.approx(0.1)
    assert ans.target == pytest.approx([goals[j] for j in JOINT_IDS])
    # Out of range in absolute mode: clipped to the config's limits, never beyond.
    rig2 = Rig(max_delta=1.0)
    key = rig2.start(mode="absolute")
    big = [10.0] * 20
    rig2.policy.offer(PolicyAction.signed("me", key, 1, big))
    for seq in range(2, 40):
        rig2.step()
        rig2.step(2)
        rig2.policy.offer(PolicyAction.signed("me", key, seq, big))
    for jid in JOINT_IDS:
        j = rig2.robot.by_id[jid]
        assert rig2.pos[jid] <= j.max_rad + 1e-9
    assert any(c.startswith("joint limits") for c in rig2.applied()[-1].clipped)


def test_refusals_name_the_reason() -> None:
    rig = Rig(burst=2)
    zero = [0.0] * 20
    assert "no policy stream" in rig.policy.offer(PolicyAction.signed("me", KEY, 1, zero))
    key = rig.start()
    assert "not the stream's holder" in rig.policy.offer(PolicyAction.signed("x", key, 1, zero))
    assert "mac" in rig.policy.offer(PolicyAction.signed("me", KEY, 1, zero))
    rig.step(50)
    assert rig.policy.offer(PolicyAction.signed("me", key, 5, zero)) == ""
    assert "replayed" in rig.policy.offer(PolicyAction.signed("me", key, 5, zero))
    # Burst 2 at one instant: the third is too fast.
    rig.policy.offer(PolicyAction.signed("me", key, 6, zero))
    assert "too fast" in rig.policy.offer(PolicyAction.signed("me", key, 7, zero))
    assert set(rig.policy.refused) == {"no_stream", "not_holder", "bad_mac", "old_seq", "too_fast"}


def test_actions_answering_observations_are_paced_by_them_not_by_when_they_arrive() -> None:
    rig = Rig(burst=1)
    zero = [0.0] * 20
    key = rig.start()
    rig.step(20)
    ticks = [m.tick for t, m in rig.sent if t == "obs"][-5:]  # type: ignore[attr-defined]
    assert len(ticks) == 5 and len(set(ticks)) == 5
    # Sent as each observation came, delivered at one instant (a loaded machine bunches
    # them): each answers an observation of its own, so none is too fast; the newest
    # overtakes the others in the mailbox (counted).
    for seq, tick in enumerate(ticks, 1):
        assert rig.policy.offer(PolicyAction.signed("me", key, seq, zero, tick)) == ""
    assert rig.policy.counts["overruns"] == 4
    # A second answer to an observation is too fast, and so is one to an older observation.
    for seq, tick in ((6, ticks[-1]), (7, ticks[0])):
        why = rig.policy.offer(PolicyAction.signed("me", key, seq, zero, tick))
        assert "too fast" in why and "answered already" in why
    # A tick no observation had is paced by the rate and `burst` (1): the second at the same
    # instant is too fast.
    future = ticks[-1] + 1000
    assert rig.policy.offer(PolicyAction.signed("me", key, 8, zero, future)) == ""
    assert "too fast" in rig.policy.offer(PolicyAction.signed("me", key, 9, zero, future + 1))
    rig.step()
    assert rig.applied()[-1].seq == 8


def test_the_seqs_an_action_skips_are_counted_lost() -> None:
    rig = Rig(burst=1)
    zero = [0.0] * 20
    key = rig.start()

    def offer(*seqs: int) -> list[str]:
        """Offer ``seqs`` at one instant, then let the next tick take the newest."""
        whys = [rig.policy.offer(PolicyAction.signed("me", key, seq, zero)) for seq in seqs]
        rig.step(3)  # a period at 50 Hz: the pace has room for the next one
        return whys

    # A stream's first action skips nothing, whatever its seq: seqs need only increase.
    assert offer(1) + offer(2) + offer(5) == ["", "", ""]
    assert rig.policy.counts["lost"] == 2  # 3 and 4
    # A duplicate, and 3 arriving after 5 (a replay or a late one, the daemon cannot tell):
    # neither is after the newest, so both are refused and the count of lost stays.
    assert all("replayed" in why for why in offer(5, 3))
    assert rig.policy.counts["lost"] == 2 and rig.policy.refused["old_seq"] == 2
    # A refused action's seq is the stream's newest all the same: 7, too fast behind 6, is
    # refused and not also lost when 8 comes.
    assert offer(6, 7)[1].startswith("too fast") and offer(8) == [""]
    assert rig.policy.counts["lost"] == 2
    assert [a.seq for a in rig.applied()] == [1, 2, 5, 6, 8]
    # Each seq from 1 to the newest, 8, is applied, overrun, lost or refused, once (the two
    # old seqs refused were seqs counted already).
    c = rig.policy.counts
    assert c["applied"] + c["overruns"] + c["lost"] + rig.policy.refused["too_fast"] == 8
    # A new stream starts a new sequence; the count is the daemon's life's, as `applied` is.
    key = rig.start()
    assert offer(100) + offer(103) == ["", ""]
    status = rig.policy.policy_status()
    assert status.lost == 4 and PolicyStatus.from_dict(status.to_dict()).lost == 4


def test_silence_holds_then_damps_then_safe_stops() -> None:
    rig = Rig(damp_after=0.1, silence_timeout=0.3)
    key = rig.start()
    rig.policy.offer(PolicyAction.signed("me", key, 1, [0.0] * 20))
    rig.step()
    rig.step(int(0.05 / DT))
    assert rig.policy.state == "holding" and rig.policy.counts["missed"] >= 1
    rig.step(int(0.06 / DT))
    assert rig.policy.state == "damping"
    assert all(p == 8 for p, _, _ in rig.policy.gains().values())
    rig.step(int(0.25 / DT))
    assert rig.policy.state == "stopped" and "silence" in rig.policy.reason
    assert not rig.policy.owned()  # the joints went back to the manager, which holds the pose


@pytest.mark.parametrize("cause", ["tilt", "limit", "alarm"])
def test_a_fall_a_joint_limit_or_an_alarm_ends_the_stream(cause: str) -> None:
    rig = Rig()
    key = rig.start()
    rig.policy.offer(PolicyAction.signed("me", key, 1, [0.0] * 20))
    rig.step()
    if cause == "tilt":
        rig.accel = np.array([GRAVITY * math.sin(0.7), 0.0, GRAVITY * math.cos(0.7)])
    elif cause == "limit":
        rig.pos[13] = rig.robot.by_id[13].max_rad + 0.2
    else:
        rig.alarm = "temperature alarm: r_knee at 75 °C"
    for seq in range(2, 200):
        rig.step(2)
        rig.policy.offer(PolicyAction.signed("me", key, seq, [0.0] * 20))
        if cause == "limit":
            rig.pos[13] = rig.robot.by_id[13].max_rad + 0.2
        rig.step()
        if rig.policy.state == "stopped":
            break
    words = {"tilt": "fall", "limit": "joint limit hit: r_knee", "alarm": "temperature"}[cause]
    assert rig.policy.state == "stopped" and words in rig.policy.reason


def test_observations_are_published_at_the_rate_relative_to_the_default_pose() -> None:
    rig = Rig(observe_hz=25.0)
    rig.step(int(1.0 / DT))
    obs = [m for t, m in rig.sent if t == "obs"]
    assert 24 <= len(obs) <= 26
    assert obs[-1].joint_pos == pytest.approx([0.0] * 20, abs=1e-12)
    assert obs[-1].gravity == pytest.approx([0, 0, -1])


def test_the_policy_section_is_read_with_unknown_keys_refused() -> None:
    s = PolicySettings.from_config(load_all()["policy"])
    assert s.rate_hz == 50.0
    from schemas.errors import ConfigError

    with pytest.raises(ConfigError, match="max_delt"):
        PolicySettings.from_config({"max_delt": 1.0})
