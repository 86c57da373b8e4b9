"""``darwin tui`` in a real terminal (tmux), driven by keys as a person over SSH would, against
a real daemon; the screen is read back with ``capture-pane``."""

from __future__ import annotations

import os
import shutil
import subprocess
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.fixtures.system import REPO, RunningSystem, darwin_command, start_system

DEADLINE_S = 30.0


class Tmux:
    """One tmux server of its own (``-L``), killed at the end."""

    def __init__(self, socket: str) -> None:
        self.socket = socket
        self.target = "tui"

    def run(self, *args: str) -> str:
        out = subprocess.run(
            ["tmux", "-L", self.socket, *args], capture_output=True, text=True, timeout=10
        )
        if out.returncode != 0:
            raise RuntimeError(f"tmux {' '.join(args)} failed: {out.stderr.strip()}")
        return out.stdout

    def has_session(self) -> bool:
        # The server exits with its last session, so "no server" means the program ended too.
        out = subprocess.run(
            ["tmux", "-L", self.socket, "has-session", "-t", self.target],
            capture_output=True,
            timeout=10,
        )
        return out.returncode == 0

    def screen(self) -> str:
        return self.run("capture-pane", "-p", "-t", self.target)

    def keys(self, *keys: str) -> None:
        self.run("send-keys", "-t", self.target, *keys)

    def wait_for(self, text: str) -> str:
        """Poll the screen until ``text`` shows (a generous deadline, not a timing)."""
        deadline = time.monotonic() + DEADLINE_S
        screen = ""
        while time.monotonic() < deadline:
            screen = self.screen()
            if text in screen:
                return screen
            time.sleep(0.1)
        raise AssertionError(f"{text!r} never showed; the screen was:\n{screen}")


@pytest.fixture
def tmux(tmp_path: Path) -> Iterator[Tmux]:
    if shutil.which("tmux") is None:
        raise RuntimeError("tmux is needed for this test: apt-get install -y tmux")
    t = Tmux(f"darwin-test-{uuid.uuid4().hex[:8]}")
    try:
        yield t
    finally:
        subprocess.run(["tmux", "-L", t.socket, "kill-server"], capture_output=True, timeout=10)


@pytest.fixture
def own_system() -> Iterator[RunningSystem]:
    # A daemon of its own: the shared one has served every UI test of this worker before (in
    # two CI runs, overloaded with a thousand overruns, the TUI's screen froze on the log tab).
    with start_system(gateway=False) as system:
        yield system


def test_tui_in_tmux(own_system: RunningSystem, tmux: Tmux, tmp_path: Path) -> None:
    robot_system = own_system
    env = {
        "XDG_CONFIG_HOME": str(tmp_path / "config"),
        "TERM": "xterm-256color",
        "COLORTERM": "truecolor",
        "LANG": "C.UTF-8",
        "PATH": os.environ.get("PATH", ""),
    }
    command = darwin_command(
        "tui",
        "--connect", robot_system.endpoint, "--robot", robot_system.robot,
        "--name", "ssh-user", "--lang", "en",
    )  # fmt: skip
    env_args = [f"{k}={v}" for k, v in env.items()]
    shell = " ".join(["cd", str(REPO), "&&", "env", *env_args, *command])
    tmux.run("new-session", "-d", "-s", tmux.target, "-x", "100", "-y", "30", shell)
    tmux.wait_for("connected")
    tmux.wait_for("Accelerometer")
    tmux.keys("2")
    tmux.wait_for("r_shoulder_pitch")
    tmux.keys("l")
    tmux.wait_for("lease: you")
    tmux.keys("F2")
    tmux.wait_for("Motores")
    tmux.wait_for("controlo: você")
    tmux.keys("C-x", "7")
    tmux.wait_for("halt")
    tmux.keys("l")
    tmux.wait_for("controlo: livre")
    tmux.keys("C-q")
    deadline = time.monotonic() + DEADLINE_S
    while tmux.has_session():
        assert time.monotonic() < deadline, "darwin tui did not quit on ctrl+q"
        time.sleep(0.1)
    saved = (tmp_path / "config" / "darwin" / "tui.toml").read_text()
    assert robot_system.endpoint in saved and 'lang = "pt"' in saved
