"""The shell commands of docs/doctor.md, docs/servo-replacement.md and docs/calibration.md that
run on the simulator, taken from the pages themselves and run as written (the emulator's link
path moved into a temporary directory)."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from tests.fixtures.system import REPO, darwin_command, stop_group
from tests.unit.test_calibrate_import import SAMPLE_INI

DOCS = REPO / "docs"
LINK = "/tmp/darwin-sim-tty"


def commands(page: str, after: str = "") -> list[list[str]]:
    """``darwin …`` lines of the ```sh blocks of ``page`` (below the heading ``after``)."""
    text = (DOCS / page).read_text()
    if after:
        text = text[text.index(after) :]
    out = []
    for block in re.findall(r"```sh\n(.*?)```", text, re.S):
        for line in block.splitlines():
            line = line.split("#", 1)[0].strip().rstrip("&").strip()
            if line.startswith("darwin "):
                out.append(shlex.split(line)[1:])
    return out


@contextmanager
def sim(args: list[str]) -> Iterator[None]:
    proc = subprocess.Popen(
        darwin_command(*args), stdout=subprocess.PIPE, text=True, cwd=REPO, start_new_session=True
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.startswith("port: "), line
        yield
    finally:
        stop_group(proc)
        if proc.stdout is not None:
            proc.stdout.close()


def run(
    args: list[str], cwd: Path, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    out = subprocess.run(
        darwin_command(*args), capture_output=True, text=True, timeout=300, cwd=cwd,
        env={**os.environ, **(env or {})},
    )
    assert "Traceback" not in out.stderr, out.stderr
    return out


def localise(cmds: list[list[str]], tmp_path: Path) -> list[list[str]]:
    link = str(tmp_path / "tty")
    return [[link if a == LINK else a for a in c] for c in cmds]


def test_doctor_page(tmp_path: Path) -> None:
    (start, doctor), = [localise(commands("doctor.md", "## Trying it"), tmp_path)]
    assert start[0] == "sim" and doctor[0] == "doctor"
    with sim(start):
        out = run([*doctor, "--connect", "tcp/127.0.0.1:9"], REPO)
    assert out.returncode == 1
    # The lines the page shows, word for word.
    shown = (DOCS / "doctor.md").read_text().split("prints, among its lines", 1)[1]
    shown = shown.split("```", 2)[1].strip().splitlines()
    assert len(shown) == 3
    printed = out.stdout.splitlines()
    for line in shown:
        assert line in printed, out.stdout


def test_servo_replacement_page(tmp_path: Path) -> None:
    page = commands("servo-replacement.md", "## On the simulator")
    start, replace, doctor = localise(page, tmp_path)
    assert (start[0], replace[:2], doctor[0]) == ("sim", ["servo", "replace"], "doctor")
    with sim(start):
        done = run(replace, REPO)
        assert done.returncode == 0, done.stderr
        assert "servo 5: ID 5, 1000000 bps" in done.stdout
        after = run([*doctor, "--connect", "tcp/127.0.0.1:9"], REPO)
    assert "OK    servos: 20/20 MX-28" in after.stdout, after.stdout


def test_calibration_page(tmp_path: Path) -> None:
    (tmp_path / "config.ini").write_text(SAMPLE_INI)
    user = tmp_path / "user.toml"
    dry, real = commands("calibration.md")
    out = run(dry, tmp_path, {"DARWIN_CONFIG": str(user)})
    assert out.returncode == 0 and "dry run" in out.stdout and not user.exists()
    out = run(real, tmp_path, {"DARWIN_CONFIG": str(user)})
    assert out.returncode == 0 and f"config: {user}" in out.stdout
    assert "[robot.joints.r_knee]" in user.read_text()
