"""A computer that cannot keep the motion loop says so: a daemon asked for a tick its bus alone
cannot fit (1 ms; a bulk read of 21 devices is ~3.5 ms of wire) raises the overload alarm in
its status and events, and ``darwin list`` shows it."""

from __future__ import annotations

import json
import subprocess

from tests.fixtures.emulator import darwin_command
from tests.fixtures.system import start_system


def test_sustained_overruns_raise_the_alarm_every_ui_reads() -> None:
    with start_system(gateway=False, extra_args=["--tick-ms", "1"]) as system:
        with system.robot_client(name="overload test") as robot:
            # (The loop_overloaded event is tested on LoopStats: here it may precede us.)
            status = robot.wait_for("status", lambda s: s.loop.get("overloaded"), timeout=60)
            assert status.loop["overrun_pct"] >= 5.0
            assert status.loop["tick_ms"] == 1.0
        out = subprocess.run(
            darwin_command("list", "--connect", system.endpoint, "--json", "--wait", "5"),
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert out.returncode == 0, out.stderr
        records = json.loads(out.stdout)
        assert [r["loop_overloaded"] for r in records if r["name"] == system.robot] == [True]
        line = subprocess.run(
            darwin_command("list", "--connect", system.endpoint, "--wait", "5"),
            capture_output=True,
            text=True,
            timeout=60,
        ).stdout
        assert "OVERLOADED" in line
