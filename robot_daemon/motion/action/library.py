"""The set of action pages the daemon can play: the project's own library under
``config/motions/`` (text), or any ROBOTIS ``.bin`` / text file named in config ``[motion] file``.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from config.loader import CONFIG_DIR, RobotConfig
from robot_daemon.motion.action import binfile, textfile
from robot_daemon.motion.action.binfile import MotionFileError, Page
from robot_daemon.motion.action.check import limit_problems

LIBRARY_DIR = CONFIG_DIR / "motions"


def _key(name: str) -> str:
    return " ".join(name.lower().replace("_", " ").replace("-", " ").split())


class MotionLibrary:
    """Pages by number and by name (case, spaces, ``_`` and ``-`` do not matter)."""

    def __init__(self, pages: Iterable[Page]) -> None:
        self.pages: dict[int, Page] = {}
        for p in pages:
            if p.zero or p.number == 0 or not p.steps:
                continue
            self.pages[p.number] = p
        self._by_name: dict[str, int] = {}
        for n in sorted(self.pages):
            self._by_name.setdefault(_key(self.pages[n].name), n)

    def __len__(self) -> int:
        return len(self.pages)

    def __contains__(self, number: object) -> bool:
        return number in self.pages

    def page(self, ref: int | str) -> Page:
        """A page by number or name; ``KeyError`` with a helpful message otherwise."""
        if isinstance(ref, str) and ref.strip().isdigit():
            ref = int(ref)
        if isinstance(ref, int):
            if ref not in self.pages:
                raise KeyError(
                    f"no action page {ref}; pages are {', '.join(map(str, sorted(self.pages)))}"
                )
            return self.pages[ref]
        number = self._by_name.get(_key(ref))
        if number is None:
            raise KeyError(f"no action page named {ref!r}; names are {', '.join(self.names())}")
        return self.pages[number]

    def chain(self, number: int) -> list[int]:
        """The page and every page it leads to through ``next`` and ``exit``."""
        seen: list[int] = []
        todo = [number]
        while todo:
            n = todo.pop()
            if n in seen or n not in self.pages:
                continue
            seen.append(n)
            todo += [self.pages[n].next, self.pages[n].exit]
        return seen

    def names(self) -> list[str]:
        return [self.pages[n].name for n in sorted(self.pages)]

    def listing(self) -> list[dict[str, object]]:
        return [
            {"page": n, "name": p.name, "steps": len(p.steps), "next": p.next, "exit": p.exit}
            for n, p in sorted(self.pages.items())
        ]

    def violations(self, robot: RobotConfig, numbers: Iterable[int] | None = None) -> list[str]:
        """Every step target outside the configured joint limits, as readable lines."""
        wanted = sorted(self.pages) if numbers is None else [n for n in numbers if n in self]
        return [str(p) for n in wanted for p in limit_problems(self.pages[n], robot)]


def read_pages(path: str | Path) -> list[Page]:
    """Pages of a ``.bin`` file, a text file, or every ``*.toml`` in a directory."""
    p = Path(path)
    if p.is_dir():
        pages: list[Page] = []
        seen: dict[int, Path] = {}
        for f in sorted(p.glob("*.toml")):
            for page in textfile.read_text(f):
                if page.number in seen:
                    raise MotionFileError(
                        f"page {page.number} is defined in both {seen[page.number]} and {f}"
                    )
                seen[page.number] = f
                pages.append(page)
        return pages
    if p.suffix.lower() == ".bin":
        return binfile.read_bin(p)
    return textfile.read_text(p)


def load_library(path: str | Path | None = None) -> MotionLibrary:
    """The library at ``path`` (default: the project's ``config/motions/``)."""
    return MotionLibrary(read_pages(path or LIBRARY_DIR))
