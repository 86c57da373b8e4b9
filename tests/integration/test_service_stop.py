"""The boot service's stop: systemd sends SIGTERM to the daemon (KillMode=mixed: the main
process only) and waits TimeoutStopSec. A real daemon on the emulator, walking under a lease,
must halt, hold the pose and exit 0 within it, taking its emulator child with it."""

from __future__ import annotations

import signal
import threading
import uuid

from robot_daemon.service import STOP_TIMEOUT_S
from schemas.session import free_tcp_port
from tests.fixtures.system import EventLog, spawn_darwin, stop_group


def test_sigterm_holds_the_pose_and_exits_cleanly_within_the_stop_timeout() -> None:
    robot_name = f"t{uuid.uuid4().hex[:10]}"
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    proc = spawn_darwin("daemon", "--sim", "--robot", robot_name, "--listen", endpoint)
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
        from clients.robot import Robot

        with Robot(endpoint, robot_name, name="stopper") as robot:
            events = EventLog()
            robot.subscribe("events", events)
            robot.wait_for("status", lambda s: s.state in ("running", "degraded"), timeout=30)
            with robot.control():
                robot.walk(x=0.02)
                robot.wait_for(
                    "status",
                    lambda s: s.motion.get("walking", {}).get("walking") is True,
                    timeout=15,
                )
                proc.send_signal(signal.SIGTERM)  # the main process only, as systemd does
                events.wait(lambda e: e.kind == "state" and e.data.get("state") == "stopping")
            assert proc.wait(timeout=STOP_TIMEOUT_S) == 0
        reader.join(timeout=5)
        output = "\n".join(lines)
        assert "Traceback" not in output, output
        assert "holding the pose at shutdown failed" not in output, output
    finally:
        stop_group(proc)
        reader.join(timeout=5)
        if proc.stdout is not None:
            proc.stdout.close()
