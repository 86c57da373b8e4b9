"""The pages the daemon plays: the shipped library with the user's own pages on top.

The shipped pages (``config/motions/`` or ``[motion] library``) are never written. The user's
pages live in their motion library folder, one TOML file per page (``NNN_name.toml``, the
shipped layout): ``[motion] user_library``, else ``$DARWIN_MOTIONS``, else
``<user config dir>/darwin/motions``. A user page with a shipped page's number replaces it;
deleting it brings the shipped one back.

Reading is cached per file (modification time and size), so :meth:`PageStore.reload` after a
save re-reads nothing and after a hand edit only the changed files: it runs in the motion
thread. A broken user file is skipped and reported (``problems``), never stops the daemon.
Writes go to a temporary file renamed over the old one, so a crash never leaves half a page.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from config.loader import user_config_path
from robot_daemon.motion.action import binfile, textfile
from robot_daemon.motion.action.binfile import MotionFileError, Page
from robot_daemon.motion.action.library import LIBRARY_DIR, MotionLibrary

log = logging.getLogger(__name__)

ENV_USER_MOTIONS = "DARWIN_MOTIONS"


def user_library_dir(motion_settings: dict[str, Any] | None = None) -> Path:
    configured = str((motion_settings or {}).get("user_library") or "")
    if configured:
        return Path(configured).expanduser()
    if os.environ.get(ENV_USER_MOTIONS):
        return Path(os.environ[ENV_USER_MOTIONS]).expanduser()
    return user_config_path().parent / "motions"


def file_name(page: Page) -> str:
    slug = re.sub(r"[^a-z0-9]+", "_", page.name.lower()).strip("_") or "page"
    return f"{page.number:03d}_{slug}.toml"


@dataclass
class _Cached:
    """Pages read from a file, with the file's stamp when read."""

    stamp: tuple[int, int]
    pages: list[Page]


class PageStore:
    def __init__(
        self,
        names: dict[int, str],
        base: str | Path | None = None,
        user_dir: str | Path | None = None,
    ) -> None:
        self.names = names
        self.base = Path(base) if base else LIBRARY_DIR
        self.user_dir = Path(user_dir) if user_dir else user_library_dir()
        self._cache: dict[Path, _Cached] = {}
        self.problems: list[str] = []
        self.shipped: dict[int, Page] = {}
        self.user: dict[int, Page] = {}
        self.user_files: dict[int, Path] = {}
        self.reads = 0  # files parsed so far (the cache's effect shows in tests)
        self.library = MotionLibrary([])
        self.reload()

    # -- reading -----------------------------------------------------------------------------
    def _read(self, path: Path) -> list[Page]:
        st = path.stat()
        stamp = (st.st_mtime_ns, st.st_size)
        cached = self._cache.get(path)
        if cached is None or cached.stamp != stamp:
            self.reads += 1
            if path.suffix.lower() == ".bin":
                pages = binfile.read_bin(path)
            else:
                pages = textfile.read_text(path, self.names)
            cached = self._cache[path] = _Cached(stamp, pages)
        return cached.pages

    def _base_pages(self) -> dict[int, Page]:
        files = sorted(self.base.glob("*.toml")) if self.base.is_dir() else [self.base]
        out: dict[int, Page] = {}
        for f in files:
            for page in self._read(f):
                if page.number in out:
                    raise MotionFileError(f"page {page.number} is defined twice in {self.base}")
                out[page.number] = page
        return out

    def reload(self) -> dict[str, Any]:
        """Read again what changed on disk; returns counts and problems."""
        before = self.reads
        problems: list[str] = []
        shipped = self._base_pages()  # the installed library: an error here is a real fault
        user: dict[int, Page] = {}
        files: dict[int, Path] = {}
        seen: set[Path] = set()
        if self.user_dir.is_dir():
            for f in sorted(self.user_dir.glob("*.toml")):
                seen.add(f)
                try:
                    pages = self._read(f)
                except (MotionFileError, OSError) as exc:
                    problems.append(f"{f}: skipped: {exc}")
                    continue
                for page in pages:
                    if page.number in files:
                        problems.append(
                            f"{f}: page {page.number} skipped: already in {files[page.number]}"
                        )
                        continue
                    user[page.number] = page
                    files[page.number] = f
        for path in list(self._cache):
            if path.parent == self.user_dir and path not in seen:
                del self._cache[path]
        for p in problems:
            log.warning("motion library: %s", p)
        self.shipped, self.user, self.user_files, self.problems = shipped, user, files, problems
        self.library = MotionLibrary(self._merged())
        return {"pages": len(self.library), "read": self.reads - before, "problems": problems}

    def _merged(self) -> list[Page]:
        merged = {n: p for n, p in self.shipped.items() if not p.zero and p.steps}
        merged.update(self.user)
        return list(merged.values())

    def origin(self, number: int) -> str:
        if number in self.user:
            return "user (replaces shipped)" if number in self.shipped else "user"
        return "shipped"

    # -- writing -----------------------------------------------------------------------------
    def _write(self, path: Path, pages: list[Page]) -> None:
        self.user_dir.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.tmp")
        tmp.write_text(textfile.dumps(pages, self.names), encoding="utf-8")
        os.replace(tmp, path)
        # What was written is known: the reload that follows need not parse it again.
        st = path.stat()
        self._cache[path] = _Cached((st.st_mtime_ns, st.st_size), list(pages))

    def _others_in(self, path: Path, number: int) -> list[Page]:
        cached = self._cache.get(path)
        return [p for p in (cached.pages if cached else []) if p.number != number]

    def put(self, page: Page) -> Path:
        """Save ``page`` in the user library (replacing a page of that number) and use it."""
        old = self.user_files.get(page.number)
        if old is not None and self._others_in(old, page.number):
            # A hand-written file with several pages: rewrite it with this one changed.
            path = old
            self._write(path, [*self._others_in(old, page.number), page])
        else:
            path = self.user_dir / file_name(page)
            self._write(path, [page])
            if old is not None and old != path:
                with contextlib.suppress(FileNotFoundError):
                    old.unlink()
        self.reload()
        return path

    def delete(self, number: int) -> dict[str, Any]:
        """Remove the user's page ``number``; a shipped page of that number comes back."""
        path = self.user_files[number]
        others = self._others_in(path, number)
        if others:
            self._write(path, others)
        else:
            path.unlink()
        self.reload()
        return {"path": str(path), "restored": number in self.shipped}
