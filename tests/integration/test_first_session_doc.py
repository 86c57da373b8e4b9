"""The simulator command of docs/first-session.md runs and does what the page says."""

from __future__ import annotations

import os
import re
import shlex
import signal
import subprocess

from tests.fixtures.system import REPO, darwin_command

PAGE = REPO / "docs" / "first-session.md"


def rehearsal_command() -> list[str]:
    section = PAGE.read_text().split("## Rehearse on the simulator", 1)[1]
    block = re.search(r"```sh\n(.*?)```", section, re.S)
    assert block is not None
    (line,) = [x for x in block.group(1).splitlines() if x.strip()]
    args = shlex.split(line)
    assert args[0] == "darwin"
    return args[1:]


def test_the_rehearsal_command_refuses_servo_7_and_runs() -> None:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    env.pop("DARWIN_CONFIG", None)
    # Any free port: the page's default address may be taken by another test's daemon.
    args = darwin_command(*rehearsal_command(), "--listen", "tcp/127.0.0.1:0")
    proc = subprocess.Popen(
        args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=REPO, env=env
    )
    seen: list[str] = []
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            seen.append(line)
            if line.startswith("zenoh:"):
                break
        text = "".join(seen)
        assert "servo 7 (r_hip_yaw) has MX-28 firmware 26" in text, text
        assert "Traceback" not in text
    finally:
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, out
    assert "fell" not in out and "get up" not in out
