"""What the TUI remembers between runs: ``<config dir>/darwin/tui.toml``.

The config dir is ``$XDG_CONFIG_HOME`` or ``~/.config`` (``%APPDATA%`` on Windows). A broken
file is reported and ignored rather than stopping the UI from starting.
"""

from __future__ import annotations

import logging
import os
import tomllib
from dataclasses import asdict, dataclass
from pathlib import Path

log = logging.getLogger(__name__)


def default_path() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or os.environ.get("APPDATA")
    root = Path(base) if base else Path.home() / ".config"
    return root / "darwin" / "tui.toml"


@dataclass
class Settings:
    """What the TUI remembers between runs: the ``[tui]`` table of ``tui.toml``."""

    endpoint: str = ""
    robot: str = ""
    name: str = ""
    lang: str = ""

    @classmethod
    def load(cls, path: Path) -> Settings:
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            return cls()
        except (OSError, tomllib.TOMLDecodeError) as exc:
            log.warning("ignoring %s: %s (delete or fix it)", path, exc)
            return cls()
        section = data.get("tui", {})
        return cls(**{k: str(section[k]) for k in asdict(cls()) if k in section})

    def save(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        lines = ["# Written by `darwin tui`: the last robot it connected to.", "[tui]"]
        for key, value in asdict(self).items():
            escaped = value.replace("\\", "\\\\").replace('"', '\\"')
            lines.append(f'{key} = "{escaped}"')
        tmp = path.with_suffix(".tmp")
        tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
        tmp.replace(path)
