"""The suite's order (tests/fixtures/durations.py): the shared robot's tests first, then whole
files longest first by the recorded run, each file in its own order; the record it reads is
what ``--record-durations`` writes, under pytest-xdist too; and the suite itself runs in it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from tests.fixtures import durations

REPO = Path(durations.__file__).resolve().parents[2]

FILES = {
    "test_a.py": "def test_a1(): pass\ndef test_a2(): pass\n",
    "test_b.py": "def test_b1(): pass\ndef test_b2(): pass\ndef test_b3(): pass\n",
    "test_e.py": "import time\ndef test_e1(): time.sleep(0.6)\ndef test_e2(): pass\n",
}
RECORD = {
    "test_a.py::test_a2": 30.0,
    "test_b.py::test_b1": 9.0,
    "test_b.py::test_b2": 9.0,
    "test_b.py::test_b3": 9.0,
    "test_c.py::test_c1": 100.0,
}


def _pytest(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    for name, text in FILES.items():
        (tmp_path / name).write_text(text)
    (tmp_path / "record.json").write_text(json.dumps(RECORD))
    env = dict(os.environ, PYTHONPATH=str(REPO))
    env.pop("PYTEST_XDIST_WORKER", None)
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "tests.fixtures.durations",
         "-o", "markers=slow", "-o", "durations_record=record.json", *args],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip


@dataclass
class Item:
    """What the order reads of a collected test."""

    nodeid: str
    fixturenames: tuple[str, ...] = ()
    slow: bool = False

    def get_closest_marker(self, name: str) -> object | None:
        return True if name == "slow" and self.slow else None


def test_robot_first_then_files_longest_first_each_in_its_own_order() -> None:
    items = [
        Item("test_a.py::test_a1"),
        Item("test_a.py::test_a2"),
        Item("test_b.py::test_b1"),
        Item("test_b.py::test_b2"),
        Item("test_b.py::test_b3"),
        Item("test_c.py::test_c1"),
        Item("test_c.py::test_c2", ("robot_system",)),
        Item("test_d.py::test_d1", slow=True),
        Item("test_e.py::test_e1"),
        Item("test_e.py::test_e2"),
    ]
    durations.order(items, RECORD)  # type: ignore[arg-type]
    assert [item.nodeid for item in items] == [
        "test_c.py::test_c2",  # the shared robot's, though its file's other test is the longest
        "test_c.py::test_c1",
        "test_d.py::test_d1",  # unknown, marked slow: a minute
        "test_a.py::test_a1",  # a file's time is its tests' sum: 30 beats b's 3 x 9
        "test_a.py::test_a2",
        "test_b.py::test_b1",
        "test_b.py::test_b2",
        "test_b.py::test_b3",
        "test_e.py::test_e1",  # unknown: short, in collection order
        "test_e.py::test_e2",
    ]


def test_the_record_written_under_xdist_holds_the_slow_tests_only(tmp_path: Path) -> None:
    out = tmp_path / "written.json"
    done = _pytest(tmp_path, "-q", "-n", "2", "--record-durations", str(out))
    assert done.returncode == 0, done.stdout + done.stderr
    written = json.loads(out.read_text())
    assert list(written) == ["test_e.py::test_e1"]
    assert written["test_e.py::test_e1"] >= 0.6
    assert durations.recorded(out) == written


def test_a_missing_or_broken_record_orders_by_the_marks_alone(tmp_path: Path) -> None:
    assert durations.recorded(tmp_path / "none.json") == {}
    (tmp_path / "bad.json").write_text("[1, 2")
    assert durations.recorded(tmp_path / "bad.json") == {}


def test_the_suite_has_a_record_to_run_in() -> None:
    record = durations.recorded(REPO / durations.RECORD)
    assert record and all(nodeid.startswith("tests/") for nodeid in record)
