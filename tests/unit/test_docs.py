"""The documentation is checked like code: every `darwin …` command that README.md and the pages
under docs/ show is parsed by the parser that program runs (a renamed or removed option fails
here), the CLI reference is in step with the programs' --help, and the site builds with strict
link checking."""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from robot_daemon.launch.cli import COMMANDS, command_parser

REPO = Path(__file__).resolve().parents[2]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
SHELL_LANGUAGES = {"", "sh", "bash", "console", "shell"}
DARWIN = re.compile(r"^(?:\S*/)?darwin$")


def _shell_blocks(text: str) -> list[str]:
    """The bodies of a page's fenced blocks in a shell language (or none)."""
    blocks, body, language = [], [], None
    for line in text.splitlines():
        if line.lstrip().startswith("```"):
            if language is None:
                language = line.lstrip()[3:].split(" ")[0].strip()
                body = []
            else:
                if language in SHELL_LANGUAGES:
                    blocks.append("\n".join(body))
                language = None
        elif language is not None:
            body.append(line)
    return blocks


def _commands(text: str) -> list[str]:
    """Every `darwin …` invocation in a page's shell blocks, one string each."""
    found = []
    for block in _shell_blocks(text):
        joined = block.replace("\\\n", " ")
        for line in joined.splitlines():
            line = line.strip().removeprefix("$ ")
            if not line or line.startswith("#"):
                continue
            try:
                words = shlex.split(line, comments=True)
            except ValueError:
                continue
            segment: list[str] = []
            for word in [*words, "&&"]:
                if word in {"&&", "||", "|", ";", "&"} or word.endswith(";"):
                    if segment and DARWIN.match(segment[0]):
                        found.append(shlex.join(segment))
                    segment = []
                else:
                    segment.append(word)
    return found


def _documented() -> list[tuple[str, str]]:
    return [(str(page.relative_to(REPO)), cmd) for page in PAGES
            for cmd in _commands(page.read_text())]


def test_the_pages_show_commands() -> None:
    """The extractor finds commands (a broken regex would make the next test vacuous)."""
    pages = {page for page, _ in _documented()}
    assert {"README.md", "docs/serial-bus.md", "docs/fleet.md"} <= pages


@pytest.mark.parametrize(("page", "command"), _documented())
def test_documented_command_parses(page: str, command: str) -> None:
    words = shlex.split(command)
    assert len(words) > 1, f"{page}: `{command}` names no subcommand"
    name, args = words[1], words[2:]
    assert name in COMMANDS, f"{page}: `{command}`: darwin has no command {name!r}"
    _, parser = command_parser(name)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            parser.parse_args(args)
        except SystemExit as exc:
            assert exc.code == 0, f"{page}: `{command}` does not parse: {err.getvalue()}"


def test_reference_pages_are_in_step_with_programs_and_spec() -> None:
    run = subprocess.run([sys.executable, "scripts/reference.py", "--check"], cwd=REPO,
                         capture_output=True, text=True, env={**os.environ, "CI": "1"})
    assert run.returncode == 0, run.stderr


def test_readme_links_reach_pages() -> None:
    links = re.findall(r"\]\((docs/[^)#]+)", (REPO / "README.md").read_text())
    assert links, "README links no docs page"
    missing = [link for link in links if not (REPO / link).exists()]
    assert not missing


def test_site_builds_strict(tmp_path: Path) -> None:
    mkdocs = shutil.which("mkdocs", path=str(Path(sys.executable).parent))
    assert mkdocs, "mkdocs is part of the test extra"
    run = subprocess.run([mkdocs, "build", "--strict", "--site-dir", str(tmp_path / "site")],
                         cwd=REPO, capture_output=True, text=True,
                         env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert run.returncode == 0, run.stderr[-3000:]
