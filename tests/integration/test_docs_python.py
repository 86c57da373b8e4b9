"""The Python of README.md and of the tutorials runs as written, against a running `darwin up`
(the simulator with its camera), in a fresh interpreter as a reader runs it, and prints what the
page says it prints.

A page's ```python blocks run in order in one script (later steps use what earlier ones made, as
in one notebook or one file). A ```text block that follows a python block, with no other fenced
block between, is that block's output as shown on the page: the script must print exactly those
lines, numbers aside (a position or a voltage differs from run to run; words, units and the
number of values do not). The script must end by itself: a tutorial that leaves a thread or a
session open would hang here (the timeout is a hang detector, not a speed limit)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.fixtures.system import REPO, RunningSystem, start_system

# One system for all of them, first-run first: its ball play needs the ball where `darwin up`
# puts it; the others do not care where the robot stands. docs/owner.md's first move runs on
# the simulator here: the script is the robot's, unchanged.
PAGES = ["docs/first-run.md", "README.md", "docs/notebook.md", "docs/owner.md"]
HANG = 300.0
MARK = "---- block {} ----"
FENCE = re.compile(r"^```(\S*)[^\n]*\n(.*?)^```\s*$", re.M | re.S)
NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def blocks(page: str) -> list[tuple[str, str | None]]:
    """The page's python blocks, each with the output block that follows it (or None)."""
    found: list[tuple[str, str | None]] = []
    for match in FENCE.finditer((REPO / page).read_text()):
        language, body = match.group(1), match.group(2)
        if language == "python":
            found.append((body, None))
        elif language == "text" and found and found[-1][1] is None:
            found[-1] = (found[-1][0], body)
        elif found and found[-1][1] is None:
            found[-1] = (found[-1][0], "")  # another block came first: no output shown
    return found


def script(page: str) -> str:
    parts = []
    for i, (body, _) in enumerate(blocks(page)):
        parts.append(f"print({MARK.format(i)!r}, flush=True)\n{body}")
    return "\n".join(parts)


def shape(text: str) -> list[str]:
    return [NUMBER.sub("N", line.rstrip()) for line in text.strip().splitlines()]


def test_the_pages_show_python_and_output() -> None:
    """The extractor finds blocks and outputs (a broken pattern would make the next vacuous)."""
    tutorial = blocks("docs/first-run.md")
    assert len(tutorial) >= 2 and all(out for _, out in tutorial), tutorial
    assert blocks("README.md") and blocks("docs/notebook.md")


@pytest.fixture(scope="module")
def simulated() -> Iterator[RunningSystem]:
    """`darwin up` as a reader starts it, with its own (simulated) camera. Each script ends
    with the lease released, so the next page finds the robot free. The start's timeout is a
    hang detector for a loaded machine, not a speed limit."""
    with start_system(camera=None, timeout=120.0) as system:
        yield system


@pytest.mark.parametrize("page", PAGES)
def test_the_python_of_the_page_runs_as_written(
    page: str, tmp_path: Path, simulated: RunningSystem
) -> None:
    source = tmp_path / "page.py"
    source.write_text(script(page))
    env = {**os.environ, "DARWIN_ENDPOINT": simulated.endpoint, "DARWIN_ROBOT": simulated.robot}
    try:
        run = subprocess.run(
            [sys.executable, str(source)], cwd=tmp_path, env=env, capture_output=True,
            text=True, timeout=HANG,
        )
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f"{page}: the script did not end: {exc.stdout!r} {exc.stderr!r}")
    assert run.returncode == 0, f"{page}:\n{run.stdout}\n{run.stderr}"
    printed = re.split(r"^---- block \d+ ----\n", run.stdout, flags=re.M)[1:]
    for i, ((_, expected), got) in enumerate(zip(blocks(page), printed, strict=True)):
        if expected is not None:
            assert shape(got) == shape(expected), f"{page}, python block {i + 1}:\n{got}"
