"""The live LeRobot recorder's pairing, on real Zenoh sessions on loopback: an observation answered
by the policy takes the applied target (whichever of action and answer comes first), one nobody
answered takes the next positions flagged takeover, a policy frame never answered falls back after
the answer window, and the frames are taken at --fps on the daemon's clock."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import zenoh

from clients.learn.live_record import ANSWER_WINDOW, LiveRecorder
from schemas.errors import RobotUnreachableError
from schemas.keys import Keys
from schemas.messages import encode
from schemas.policy import (
    DEFAULT_POSE,
    DEFAULT_SCALE,
    PolicyAction,
    PolicyApplied,
    PolicyObservation,
)

pytest.importorskip("pyarrow", reason="pip install -e '.[learn]' runs this test")
KEYS = Keys("rec1")


def until(condition: Callable[[], object], what: str) -> None:
    deadline = time.monotonic() + 20.0
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")


def answers(control: Any) -> bool:
    try:
        control.status()
    except RobotUnreachableError:
        return False
    return True


def obs(tick: int, stamp: float, position: float, running: bool) -> bytes:
    return encode(PolicyObservation(
        joint_pos=[position] * 20, joint_vel=[0.0] * 20, gyro=[0.0] * 3, gravity=[0.0, 0.0, -1.0],
        last_action=[0.0] * 20, command=[0.0] * 3, stamp=stamp, tick=tick, running=running,
    ))  # fmt: skip


def applied(seq: int, offset_rad: float) -> bytes:
    target = [d + offset_rad for d in DEFAULT_POSE]
    return encode(PolicyApplied(seq=seq, action=[0.0] * 20, target=target, tick=0))


def test_frames_pair_observations_with_what_answered_them(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], tmp_path: Path
) -> None:
    server, client = zenoh_pair
    rec = LiveRecorder(client, KEYS, tmp_path / "d", fps=50, task="t", camera=False).start()
    pubs = {w: server.declare_publisher(KEYS.policy(w)) for w in ("obs", "action", "applied")}
    until(lambda: all(p.matching_status.matching for p in pubs.values()), "the subscriptions")

    def put(what: str, payload: bytes) -> None:
        pubs[what].put(payload)

    # Ticks at 125 Hz: observations every 2.5 ticks; a 50 fps dataset takes every one.
    put("obs", obs(10, 1.00, 0.03, running=False))  # nobody drives: takeover
    put("obs", obs(12, 1.02, 0.06, running=True))  # answered: action, then its answer
    put("action", encode(PolicyAction.signed("c", b"k", 1, [0.0] * 20, obs_tick=12)))
    put("applied", applied(1, 0.09))
    put("obs", obs(15, 1.03, 0.09, running=True))  # 10 ms later: not a frame at 50 fps
    put("obs", obs(17, 1.04, 0.09, running=True))  # answered: the answer before its action
    put("applied", applied(2, 0.12))
    put("action", encode(PolicyAction.signed("c", b"k", 2, [0.0] * 20, obs_tick=17)))
    # Keys are delivered independently: let the answers land before the window closes on them.
    until(lambda: rec.stats.frames >= 3, "the answered frames")
    put("obs", obs(20, 1.06, 0.12, running=True))  # never answered: the window's fallback
    for k in range(ANSWER_WINDOW):
        put("obs", obs(22 + 2 * k, 1.08 + 0.02 * k, 0.15, running=True))
    put("action", b"\x00not msgpack")  # malformed: nobody's frame
    until(lambda: rec.stats.frames >= 4, "four frames complete")
    stats = rec.stop()
    assert stats.episodes == 1 and stats.dropped == 0

    data = pd.read_parquet(tmp_path / "d/data/chunk-000/file-000.parquet")
    actions = np.stack(data["action"].to_numpy())[:, 0] * DEFAULT_SCALE  # back to rad offsets
    assert list(data["takeover"])[:4] == [True, False, False, False]
    # takeover: the next observation's position; policy: the applied target's offset; the
    # unanswered one: the positions ANSWER_WINDOW observations later.
    assert actions[:4] == pytest.approx([0.06, 0.09, 0.12, 0.15])
    assert len(data) == 4 + ANSWER_WINDOW  # the 10 ms observation was not taken


def test_the_record_control_op_ends_an_episode_and_names_a_bad_op(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], tmp_path: Path
) -> None:
    from clients.recording.control import RecordControl
    from schemas.errors import InvalidCommandError

    server, client = zenoh_pair
    rec = LiveRecorder(client, KEYS, tmp_path / "d", fps=50, camera=False).start()
    try:
        pub = server.declare_publisher(KEYS.policy("obs"))
        until(lambda: pub.matching_status.matching, "the subscription")
        control = RecordControl(server, "rec1")
        # The control's queryable is declared after the subscriptions: seen matching, it may
        # not have reached this session yet (a query then finds nobody, at once).
        until(lambda: answers(control), "the record control")
        for k in range(3):
            pub.put(obs(10 + k * 3, 1.0 + k * 0.02, 0.0, running=False))
        until(lambda: control.status()["open_frames"] >= 2, "frames")
        assert control.episode(task="next") == {"ended": 0, "episode": 1, "task": "next"}
        with pytest.raises(InvalidCommandError, match="unknown op"):
            control._ask("rewind")
        with pytest.raises(InvalidCommandError, match="task must be a string"):
            control._ask("episode", task=7)
    finally:
        rec.stop()
