"""Physics tests: the MuJoCo plant under the emulator. They need the physics extra
(`pip install -e '.[physics]'`, which CI installs); without it they are skipped, saying so."""

from __future__ import annotations

import importlib.util

import pytest

if importlib.util.find_spec("mujoco") is None:
    pytest.skip(
        "mujoco is not installed: pip install -e '.[physics]' runs these tests",
        allow_module_level=True,
    )
