"""`darwin web` in real headless Chromium: the header with the robot's name, live joint numbers,
a tab key, and a screenshot written as a test artifact (test-artifacts/web.png).

The terminal is drawn on a canvas, so the screen is read from the page's own xterm.js buffer:
a script installed before the page loads keeps a reference to the terminal textual-serve
creates (its only handle is a ``terminal`` property on the session object)."""

from __future__ import annotations

import os
import subprocess
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

from schemas.session import free_tcp_port
from tests.browser import Page, chromium
from tests.fixtures.emulator import wait_until
from tests.fixtures.system import (
    REPO,
    RunningSystem,
    darwin_command,
    start_system,
    stop_group,
)

DEADLINE_S = 60.0
ARTIFACTS = Path(os.environ.get("DARWIN_TEST_ARTIFACTS", REPO / "test-artifacts"))

KEEP_TERMINAL = """
Object.defineProperty(Object.prototype, "terminal", {
  configurable: true,
  set(value) {
    Object.defineProperty(this, "terminal", {
      value, writable: true, configurable: true, enumerable: true,
    });
    window.__xterm = value;
  },
});
"""
SCREEN = """(() => {
  const t = window.__xterm;
  if (!t) return "";
  const b = t.buffer.active, rows = [];
  for (let i = 0; i < t.rows; i++) {
    const line = b.getLine(b.viewportY + i);
    rows.push(line ? line.translateToString(true) : "");
  }
  return rows.join("\\n");
})()"""

pytestmark = pytest.mark.timeout(240)


@pytest.fixture
def web(robot_system: RunningSystem, tmp_path: Path) -> Iterator[tuple[str, subprocess.Popen[str]]]:
    listen = f"127.0.0.1:{free_tcp_port()}"
    env = dict(os.environ, XDG_CONFIG_HOME=str(tmp_path / "config"), PYTHONUNBUFFERED="1")
    args = ["web", "--connect", robot_system.endpoint, "--robot", robot_system.robot]
    proc = subprocess.Popen(
        darwin_command(*args, "--listen", listen, "--lang", "en"),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=REPO,
        env=env,
        start_new_session=True,
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline().strip()
        assert line == f"web: http://{listen}", line
        yield f"http://{listen}/", proc
    finally:
        # The whole group: the server and any tab's UI process it left.
        stop_group(proc)
        if proc.stdout is not None:
            proc.stdout.close()


def wait_screen(page: Page, predicate, what: str) -> str:  # type: ignore[no-untyped-def]
    """Poll the browser's terminal until ``predicate(screen)`` (a deadline, not a timing)."""
    deadline = time.monotonic() + DEADLINE_S
    screen = ""
    while time.monotonic() < deadline:
        screen = page.evaluate(SCREEN) or ""
        if predicate(screen):
            return screen
        time.sleep(0.2)
    raise AssertionError(f"{what} never showed; the browser's screen was:\n{screen}")


def joint_row(screen: str, name: str) -> str:
    return next(line for line in screen.splitlines() if f" {name} " in line)


def tab_processes(robot: str) -> list[int]:
    """The ``darwin tui`` processes `darwin web` runs for open tabs on ``robot``."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                cmd = (entry / "cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if b"tui" in cmd and robot.encode() in cmd and b"robot_daemon.launch.cli" in cmd:
                found.append(int(entry.name))
    return found


def test_tui_in_a_browser(
    robot_system: RunningSystem, web: tuple[str, subprocess.Popen[str]]
) -> None:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    robot = robot_system.robot
    url, server = web
    with chromium() as page:
        page.call("Page.enable")
        page.call("Page.addScriptToEvaluateOnNewDocument", source=KEEP_TERMINAL)
        page.call("Page.navigate", url=url)
        header = wait_screen(page, lambda s: "connected" in s, "the connected header")
        assert f"DARwIn-OP {robot}" in header.splitlines()[0]
        assert "Accelerometer" in header  # the first tab (IMU)
        page.evaluate("window.__xterm.focus()")
        page.key("2")
        screen = wait_screen(page, lambda s: "r_shoulder_pitch" in s, "the Motors tab")
        assert "Accelerometer" not in screen
        before = joint_row(screen, "r_shoulder_pitch")
        # Live numbers: another client moves the joint; the browser's table follows.
        with robot_system.robot_client(name="mover") as mover, mover.control():
            mover.joint("r_shoulder_pitch", 0.4)
            # 0.4 rad is 22.9°: the row changes, and settles there.
            wait_screen(
                page, lambda s: joint_row(s, "r_shoulder_pitch") != before, "a changed joint row"
            )
            wait_screen(page, lambda s: " 22.9 " in joint_row(s, "r_shoulder_pitch"), "22.9°")
            page.screenshot(ARTIFACTS / "web.png")
            mover.halt()
        assert (ARTIFACTS / "web.png").stat().st_size > 1000
        # Stopping the server with a tab still open ends that tab's UI process too.
        assert tab_processes(robot)
        server.terminate()
        assert server.wait(timeout=30) == 0
        # Told to quit as the server shut down, the tab's UI may take a moment more to exit.
        wait_until(lambda: not tab_processes(robot), timeout=30, what="the tab's UI to end")


def test_darwin_up_web_serves_the_page() -> None:
    listen = f"127.0.0.1:{free_tcp_port()}"
    with start_system(gateway=False, extra_args=["--web", "--web-listen", listen]) as system:
        system.wait_line(lambda line: line == f"web: http://{listen}", DEADLINE_S)
        with urllib.request.urlopen(f"http://{listen}/", timeout=10) as page:
            html = page.read().decode()
        assert f'data-session-websocket-url="ws://{listen}/ws"' in html
