"""The boot service's stop: systemd sends SIGTERM to the daemon (KillMode=mixed: the main
process only) and waits TimeoutStopSec. A real daemon on a separate emulator, walking under a
lease, must end the walk's step at double support (as `halt`), hold the pose (every servo's
goal where the servo is, torque on) and exit 0 within it; the emulator, still running, shows
what the servos were left with."""

from __future__ import annotations

import math
import signal
import threading
from pathlib import Path

import pytest

from clients.robot import Robot
from robot_daemon.launch.service import STOP_TIMEOUT_S
from schemas.errors import CommandTimeoutError, RobotUnreachableError, UnavailableError
from schemas.session import free_tcp_port, open_client
from schemas.sim_control import SimControl
from tests.fixtures.emulator import start_emulator_process
from tests.fixtures.system import EventLog, spawn_darwin, stop_group


def test_sigterm_holds_the_pose_and_exits_cleanly_within_the_stop_timeout(
    tmp_path: Path,
) -> None:
    with start_emulator_process(link_dir=tmp_path) as sim:
        endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
        proc = spawn_darwin(
            "daemon", "--port", sim.port, "--robot", sim.robot, "--listen", endpoint
        )
        lines: list[str] = []
        ready = threading.Event()

        def read() -> None:
            assert proc.stdout is not None
            for line in proc.stdout:
                lines.append(line.rstrip("\n"))
                if line.startswith("zenoh: "):
                    ready.set()

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        try:
            assert ready.wait(60), "\n".join(lines)
            with Robot(endpoint, sim.robot, name="stopper") as robot:
                events = EventLog()
                robot.subscribe("events", events)
                robot.wait_for("status", lambda s: s.state in ("running", "degraded"), timeout=30)
                with robot.control():
                    robot.walk(x=0.02)
                    # In the gait (past the walk-ready page and the blend): steps are counted.
                    robot.wait_for(
                        "status",
                        lambda s: s.motion.get("walking", {}).get("steps", 0) >= 1,
                        timeout=30,
                    )
                    proc.send_signal(signal.SIGTERM)  # the main process only, as systemd does
                    # Not frozen on one foot: the walk ends its step at the next double
                    # support, then the daemon stops, holding the pose it ended in.
                    events.wait(lambda e: e.kind == "state" and e.data.get("state") == "stopping")
                    # Nothing starts again while the last step ends (nor once it has gone).
                    with pytest.raises(
                        (UnavailableError, CommandTimeoutError, RobotUnreachableError)
                    ):
                        robot.walk(x=0.02)
                    events.wait(lambda e: e.kind == "walk" and "double support" in e.message)
                    # The present pose written as the goal, on the bus.
                    events.wait(lambda e: e.kind == "halt" and "holding" in e.message)
                assert proc.wait(timeout=STOP_TIMEOUT_S) == 0
            reader.join(timeout=5)
            output = "\n".join(lines)
            assert "Traceback" not in output, output
            assert "holding the pose at shutdown failed" not in output, output
            session = open_client(sim.endpoint)
            try:
                state = SimControl(session, sim.robot).call("state")
            finally:
                session.close()
            for dxl_id, servo in state["servos"].items():
                assert servo["torque"], f"servo {dxl_id} let go"
                off = math.degrees(abs(servo["goal"] - servo["position"]))
                assert off < 3.0, f"servo {dxl_id} goal {off:.1f}° from where it is"
        finally:
            stop_group(proc)
            reader.join(timeout=5)
            if proc.stdout is not None:
                proc.stdout.close()



