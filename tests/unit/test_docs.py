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
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import urljoin, urlsplit

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
                # "sh", or the attribute form "{.sh .recipe}" (docs/robot.md)
                language = line.lstrip()[3:].lstrip("{.").split(" ")[0].strip()
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


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site as `mkdocs build --strict` makes it (it fails the build on a warning)."""
    mkdocs = shutil.which("mkdocs", path=str(Path(sys.executable).parent))
    assert mkdocs, "mkdocs is part of the test extra"
    out = tmp_path_factory.mktemp("site")
    run = subprocess.run([mkdocs, "build", "--strict", "--site-dir", str(out)],
                         cwd=REPO, capture_output=True, text=True,
                         env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert run.returncode == 0, run.stderr[-3000:]
    return out


def test_site_builds_strict(site: Path) -> None:
    assert (site / "index.html").exists()


class Page(HTMLParser):
    """What a built page shows: text outside <pre>, inline code, headings, links and ids."""

    def __init__(self) -> None:
        super().__init__()
        self.prose: list[str] = []  # text outside <pre>
        self.inline_code: list[str] = []  # <code> outside <pre>
        self.headings: list[tuple[str, str]] = []  # (tag, text) inside the article
        self.links: list[str] = []
        self.images: list[tuple[str, str, str]] = []  # (src, alt, width) inside the article
        self.ids: set[str] = set()
        self._pre = 0
        self._code: list[str] | None = None
        self._heading: tuple[str, list[str]] | None = None
        self._article = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        found = dict(attrs)
        if found.get("id"):
            self.ids.add(str(found["id"]))
        if tag == "a" and found.get("href"):
            self.links.append(str(found["href"]))
        if tag == "img" and self._article:
            self.images.append((str(found.get("src") or ""), str(found.get("alt") or ""),
                                str(found.get("width") or "")))
        if tag == "article":
            self._article = True
        elif tag == "pre":
            self._pre += 1
        elif tag == "code" and not self._pre:
            self._code = []
        elif tag in {"h1", "h2", "h3", "h4", "h5", "h6"} and self._article:
            self._heading = (tag, [])

    def handle_endtag(self, tag: str) -> None:
        if tag == "article":
            self._article = False
        elif tag == "pre":
            self._pre -= 1
        elif tag == "code" and self._code is not None:
            self.inline_code.append("".join(self._code))
            self._code = None
        elif self._heading is not None and tag == self._heading[0]:
            self.headings.append((tag, "".join(self._heading[1]).strip().rstrip("¶").strip()))
            self._heading = None

    def handle_data(self, data: str) -> None:
        if self._pre:
            return
        self.prose.append(data)
        if self._code is not None:
            self._code.append(data)
        if self._heading is not None:
            self._heading[1].append(data)


def _pages(site: Path) -> dict[Path, Page]:
    pages = {}
    for html in sorted(site.rglob("*.html")):
        if html.parent.name == "search" or html.name == "404.html":
            continue
        page = Page()
        page.feed(html.read_text())
        pages[html] = page
    return pages


# A fence Markdown did not take as one becomes inline code that starts with its info string and
# runs over lines (`sh recipe↵# the daemon↵apt-get …`).
SWALLOWED_FENCE = re.compile(r"^\{?\.?(?:sh|bash|console|shell|python|text|toml|ini|json|yaml)\b"
                             r"[^\n]*\n")


def test_code_blocks_render_as_code(site: Path) -> None:
    """No fence text outside <pre>, no fence swallowed into prose, one title per page and no
    heading that is a shell comment of a code block."""
    comments = {line.lstrip("#").strip() for page in PAGES for line in re.findall(
        r"^```.*?^```", page.read_text(), re.M | re.S) for line in line.splitlines()
        if line.startswith("#")}
    bad = []
    for html, page in _pages(site).items():
        name = str(html.relative_to(site))
        if "```" in "".join(page.prose):
            bad.append(f"{name}: ``` in the text")
        bad += [f"{name}: a fence rendered as inline code: {code[:40]!r}"
                for code in page.inline_code if SWALLOWED_FENCE.match(code)]
        titles = [text for tag, text in page.headings if tag == "h1"]
        if len(titles) != 1:
            bad.append(f"{name}: {len(titles)} top-level headings {titles}")
        bad += [f"{name}: heading {text!r} is a comment of a code block"
                for _, text in page.headings if text in comments]
    assert not bad, "\n".join(bad)


def test_every_internal_link_and_anchor_resolves(site: Path) -> None:
    pages = _pages(site)
    bad = []
    for html, page in pages.items():
        base = "/" + html.relative_to(site).as_posix()
        for href in page.links:
            if urlsplit(href).scheme or href.startswith("//"):
                continue  # another site
            url = urlsplit(urljoin(base, href))
            target = site / url.path.lstrip("/")
            if url.path.endswith("/") or target.is_dir():
                target = target / "index.html"
            if not target.exists():
                bad.append(f"{base}: {href}: no such file")
            elif url.fragment and target.suffix == ".html":
                ids = pages[target].ids if target in pages else Page().ids
                if url.fragment not in ids:
                    bad.append(f"{base}: {href}: no anchor #{url.fragment}")
    assert not bad, "\n".join(bad)


def test_every_picture_exists_and_says_what_it_shows(site: Path) -> None:
    """Each image of a page is there, in full (no thumbnail size set on it) and has alt text
    for a reader who cannot see it."""
    bad = []
    for html, page in _pages(site).items():
        base = "/" + html.relative_to(site).as_posix()
        for src, alt, width in page.images:
            if width:
                bad.append(f"{base}: {src}: shown {width} px wide, not at the column's width")
            if not (site / urlsplit(urljoin(base, src)).path.lstrip("/")).exists():
                bad.append(f"{base}: {src}: no such file")
            if len(alt.split()) < 3:
                bad.append(f"{base}: {src}: no alt text that says what it shows ({alt!r})")
    assert any(page.images for page in _pages(site).values()), "no page shows a picture"
    assert not bad, "\n".join(bad)
