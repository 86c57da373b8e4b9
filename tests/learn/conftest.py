"""Learning tests: need the learn extra (gymnasium, onnxruntime, pyarrow) and the physics extra
(mujoco); without them they are skipped, saying which to install."""

from __future__ import annotations

import importlib.util

import pytest

_MISSING = [m for m in ("mujoco", "gymnasium") if importlib.util.find_spec(m) is None]
if _MISSING:
    pytest.skip(
        f"{', '.join(_MISSING)} not installed: pip install -e '.[learn,physics]' runs these tests",
        allow_module_level=True,
    )
