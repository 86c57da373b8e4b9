"""Run the project as the core install sees it: every package of an extra (schemas/extras.py)
refuses to import, as if it were not installed. Run in its own process:

    python tests/no_extras.py darwin daemon --help     # the `darwin` command
    python tests/no_extras.py import MODULE…           # import modules, one line per failure
"""

from __future__ import annotations

import importlib
import sys
import traceback
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from schemas.extras import EXTRA_OF


class _Absent:
    """A meta path finder that makes the extras' packages missing."""

    def find_spec(self, name: str, path: object = None, target: object = None) -> None:
        if name.split(".")[0] in EXTRA_OF:
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)


def main(argv: list[str]) -> int:
    for name in list(sys.modules):
        if name.split(".")[0] in EXTRA_OF:
            sys.exit(f"{name} was imported before the blocker")
    sys.meta_path.insert(0, _Absent())
    if argv[0] == "darwin":
        from robot_daemon.launch.cli import main as darwin

        return darwin(argv[1:])
    failed = 0
    for module in argv[1:]:
        try:
            importlib.import_module(module)
        except Exception as exc:
            failed += 1
            where = traceback.extract_tb(exc.__traceback__)[-1]
            print(f"{module}: {type(exc).__name__}: {exc} ({where.filename}:{where.lineno})")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
