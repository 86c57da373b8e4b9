"""``[daemon] telemetry_hz``: joints and IMU at a lower rate than the tick, for a computer that
cannot afford two messages every 8 ms, while the loop itself runs every tick."""

from __future__ import annotations

import itertools
import threading
from pathlib import Path

from clients.robot import Robot
from schemas.messages import Imu, Joints
from tests.fixtures.system import start_system


def test_joints_and_imu_go_out_at_the_configured_rate(tmp_path: Path) -> None:
    config = tmp_path / "rate.toml"
    config.write_text("[daemon]\ntelemetry_hz = 25\n")  # one tick in five at 125 Hz
    n = 25
    with (
        start_system(gateway=False, extra_args=["--config", str(config)]) as system,
        Robot(system.endpoint, system.robot, name="rate test") as robot,
    ):
        ticks: dict[str, list[int]] = {"joints": [], "imu": []}
        done = threading.Event()

        def got(topic: str, msg: Joints | Imu) -> None:
            ticks[topic].append(msg.tick)
            if all(len(t) >= n for t in ticks.values()):
                done.set()

        subs = [
            robot.subscribe("joints", lambda m: got("joints", m)),  # type: ignore[arg-type]
            robot.subscribe("imu", lambda m: got("imu", m)),  # type: ignore[arg-type]
        ]
        assert done.wait(60), {k: len(v) for k, v in ticks.items()}
        for sub in subs:
            sub.close()
        status = robot.wait_for("status", timeout=10)
        assert status.loop["telemetry_hz"] == 25.0
        for topic, seen in ticks.items():
            window = seen[:n]
            assert window == sorted(window), topic
            # Every tick would make every gap 1; one tick in five makes them 5 (a tick
            # more or less after a late one, and on a loaded machine the loop may run
            # fewer ticks a second, so ask only that most gaps are well over one).
            gaps = sorted(b - a for a, b in itertools.pairwise(window))
            assert gaps[len(gaps) // 2] >= 3, (topic, window)
        # The joints and IMU of a tick go out together.
        assert set(ticks["joints"][:n]) & set(ticks["imu"][:n])
