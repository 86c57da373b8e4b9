"""Without the compiled hot path (no C compiler at install) the daemon runs the same tick in
Python and says so in one line naming the fix (robot_daemon/hotpath.py)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# What every test here checks once the extension is taken away: the Python path everywhere,
# and the status line the daemon prints.
FALLS_BACK = """
from robot_daemon import hotpath
from robot_daemon.motion.walking import ik
from robot_daemon.engine import broadcast
from robot_daemon.bus import bulk_receive, calibration, sensor_read
assert hotpath.compiled is None and hotpath.missing
assert ik.leg_ik_end_point is ik.leg_ik_end_point_py and broadcast._compiled is None
assert bulk_receive._compiled is sensor_read._compiled is calibration._compiled is None
print(hotpath.status)
"""

HIDDEN = """
import sys
sys.modules["robot_daemon._hotpath"] = None  # as if pip had built no extension
""" + FALLS_BACK


def test_a_missing_extension_is_one_line_naming_the_fix() -> None:
    proc = subprocess.run([sys.executable, "-c", HIDDEN], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines == ["hot path: Python (the C extension robot_daemon._hotpath is not built: "
                     "apt-get install gcc python3-dev, then pip install the project again)"]


def test_the_python_path_chosen_is_not_a_warning() -> None:
    proc = subprocess.run(
        [sys.executable, "-c", "from robot_daemon import hotpath as h; "
         "print(h.compiled is None, h.missing, h.status)"],
        capture_output=True, text=True, cwd=ROOT, timeout=120,
        env={**__import__("os").environ, "DARWIN_HOTPATH": "python"},
    )
    assert proc.stdout.strip() == "True False hot path: Python (DARWIN_HOTPATH=python)"


STALE = """
import sys, types
import robot_daemon
old = types.ModuleType("robot_daemon._hotpath")  # built before leg_servo_angles existed
for name in ("configure_leg", "leg_ik_end_point", "goals_raw", "pack_fields", "positions_list"):
    setattr(old, name, lambda *a: None)
sys.modules["robot_daemon._hotpath"] = robot_daemon._hotpath = old
""" + FALLS_BACK


def test_an_extension_older_than_its_source_runs_none_of_it_and_says_so() -> None:
    # An editable install keeps the .so it built while a pull brings new C: the daemon once
    # failed at import (AttributeError) on such a tree.
    proc = subprocess.run([sys.executable, "-c", STALE], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == [
        "hot path: Python (the C extension robot_daemon._hotpath is older than its source, it "
        "lacks leg_servo_angles, take_whole, apply_fast, joint_arrays, configure_walk, walk_pose, "
        "snapshot_lists, configure_arrays, take_run, put_ints, put_row, imu_lists, imu_arrays, "
        "packb: pip install the project again)"
    ]


def test_the_exports_are_what_the_stub_declares() -> None:
    from robot_daemon.hotpath import EXPORTS

    stub = (ROOT / "robot_daemon" / "_hotpath.pyi").read_text()
    declared = [line.split("(")[0].removeprefix("def ") for line in stub.splitlines()
                if line.startswith("def ")]
    assert sorted(declared) == sorted(EXPORTS)
