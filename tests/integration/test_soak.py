"""The five-minute form of the fleet soak (``benchmarks/soak.py``, docs/fleet.md): three robots
on an authenticated router, every kind of client, chaos every 15 s. Nothing may be left unsafe
or stuck: every kill of the lease holder ends in a safe stop, every process killed starts again
and every process ends when told, and after each router restart every robot is listed again."""

from __future__ import annotations

import json
import math
import subprocess
import sys

from tests.fixtures.system import REPO


def test_five_minutes_of_chaos_leave_no_missed_safe_stop_and_nothing_stuck() -> None:
    done = subprocess.run(
        [sys.executable, "benchmarks/soak.py", "--minutes", "5", "--period", "15", "--json"],
        capture_output=True, text=True, cwd=REPO, timeout=1200,
    )
    assert done.returncode in (0, 1), done.stderr[-3000:]
    figures = json.loads(done.stdout)
    assert figures["lease_stops_missed"] == 0, figures
    assert figures["stuck"] == 0, figures["stuck_detail"]
    assert figures["router_restarts"] >= 1
    assert math.isfinite(figures["longest_unlisted_s"]), figures
    assert figures["driver_bursts"] > 0 and figures["legacy_received"] > 0, figures
