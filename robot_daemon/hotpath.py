"""Whether the tick's compiled hot path is in use: the optional C extension
``robot_daemon._hotpath`` (the gait's leg IK, the goals' conversion to servo units, the bulk
read's answer into the servos' state, the frame's joint arrays, the messages' msgpack), built by
``pip install`` where a C compiler and Python's headers are (Debian: ``gcc python3-dev``).

Without it the same functions run in Python, which stay their definition (the extension gives
the same bits: ``tests/unit/test_hotpath.py``), and the daemon says so in one line at start.
``DARWIN_HOTPATH=python`` in the environment runs the Python path even where the extension is
built (to compare the two: ``benchmarks/tick_count.py``). docs/loop-cpu.md has the figures.
"""

from __future__ import annotations

import os
from types import ModuleType

# What the extension gives (robot_daemon/_hotpath.pyi declares the same; a unit test checks).
EXPORTS = (
    "configure_leg", "leg_ik_end_point", "goals_raw", "pack_fields", "positions_list",
    "leg_servo_angles", "take_whole", "apply_fast", "joint_arrays", "configure_walk",
    "walk_pose", "snapshot_lists", "configure_arrays", "take_run", "put_ints", "put_row",
    "imu_lists", "imu_arrays", "packb",
)  # fmt: skip


def _load() -> tuple[ModuleType | None, str]:
    if os.environ.get("DARWIN_HOTPATH", "") == "python":
        return None, "hot path: Python (DARWIN_HOTPATH=python)"
    try:
        from robot_daemon import _hotpath
    except ImportError:
        return None, ("hot path: Python (the C extension robot_daemon._hotpath is not built: "
                      "apt-get install gcc python3-dev, then pip install the project again)")
    stale = [name for name in EXPORTS if not hasattr(_hotpath, name)]
    if stale:
        # An editable install keeps the .so it built while the C source moves on (a pull):
        # running half of it would fail in the middle of an import, so none of it runs.
        return None, ("hot path: Python (the C extension robot_daemon._hotpath is older than "
                      f"its source, it lacks {', '.join(stale)}: pip install the project again)")
    return _hotpath, "hot path: compiled (robot_daemon._hotpath)"


def _read_arrays_directly(ext: ModuleType) -> bool:
    """The extension reads the dtypes the tick's arrays have (float, bool and numpy's ints)
    from numpy's array fields instead of asking each array for its buffer, once it has
    checked those fields against the buffer of an array of each (False: it asks, as before)."""
    import numpy as np

    kinds = (np.float64, np.bool_, np.int_, np.intc, np.longlong, np.intp)
    dtypes = list(dict.fromkeys(np.dtype(k) for k in kinds))
    ok: bool = ext.configure_arrays(np.ndarray, tuple(np.zeros(2, d) for d in dtypes))
    return ok


compiled, status = _load()
# Whether the extension reads numpy's arrays from their fields (False: through their buffer).
arrays_direct = compiled is not None and _read_arrays_directly(compiled)
# Not built (not chosen away): the daemon says so as a warning, shown without -v.
missing = compiled is None and ("not built" in status or "older than" in status)
