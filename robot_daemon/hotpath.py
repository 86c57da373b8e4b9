"""Whether the tick's compiled hot path is in use: the optional C extension
``robot_daemon._hotpath`` (the gait's leg IK and the goals' conversion to servo units), built by
``pip install`` where a C compiler and Python's headers are (Debian: ``gcc python3-dev``).

Without it the same functions run in Python, which stay their definition (the extension gives
the same bits: ``tests/unit/test_hotpath.py``), and the daemon says so in one line at start.
``DARWIN_HOTPATH=python`` in the environment runs the Python path even where the extension is
built (to compare the two: ``benchmarks/tick_count.py``). docs/loop-cpu.md has the figures.
"""

from __future__ import annotations

import os
from types import ModuleType


def _load() -> tuple[ModuleType | None, str]:
    if os.environ.get("DARWIN_HOTPATH", "") == "python":
        return None, "hot path: Python (DARWIN_HOTPATH=python)"
    try:
        from robot_daemon import _hotpath
    except ImportError:
        return None, ("hot path: Python (the C extension robot_daemon._hotpath is not built: "
                      "apt-get install gcc python3-dev, then pip install the project again)")
    return _hotpath, "hot path: compiled (robot_daemon._hotpath)"


compiled, status = _load()
# Not built (not chosen away): the daemon says so as a warning, shown without -v.
missing = compiled is None and "not built" in status
