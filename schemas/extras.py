"""Which optional package belongs to which extra of ``darwin-zenoh``, and the one error a missing
one gives.

The core install (``pip install darwin-zenoh``) is what the daemon needs on the robot's own
32-bit computer: Zenoh, the Dynamixel SDK, pyserial, msgpack and numpy. Everything a laptop runs
(the UIs, notebooks, Foxglove, ROS 2, recording, physics, certificates, OpenCV) is an extra, and
is imported only when it runs: at the command boundary (``darwin COMMAND`` turns the
``ModuleNotFoundError`` into :func:`explain`'s one line), through :func:`require` in library code
a notebook calls, or as a :class:`LazyModule` in a module the daemon imports but uses the package
only in one feature (OpenCV for the camera and ball play). ``pyproject.toml`` lists the same
extras; a test checks the two agree.
"""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import Any

from schemas.errors import DarwinError

# Top-level import name → the extra that installs it.
EXTRA_OF: dict[str, str] = {
    "cv2": "vision",
    "cryptography": "security",
    "textual": "tui",
    "textual_serve": "web",
    "pandas": "notebook",
    "matplotlib": "notebook",
    "ipywidgets": "notebook",
    "foxglove": "foxglove",
    "mcap": "record",
    "rosbags": "ros2",
    "xxhash": "ros2",
    "mujoco": "physics",
    "OpenGL": "physics",
    "gymnasium": "learn",
    "onnxruntime": "learn",
    "pyarrow": "learn",
}

DISTRIBUTION = "darwin-zenoh"
# On the robot (Debian 12 i386) PyPI has no wheel for these: Debian's package is the way in
# (docs/robot.md).
ON_THE_ROBOT: dict[str, str] = {"vision": "python3-opencv"}


class MissingExtraError(DarwinError, ModuleNotFoundError):
    """An optional package is not installed; the message names the extra that brings it."""

    def __init__(self, module: str, extra: str, what: str | None = None) -> None:
        self.extra = extra
        super().__init__(message(extra, what), name=module)


def explain(exc: ModuleNotFoundError) -> str | None:
    """The one line for a missing optional package (None for any other missing module)."""
    if isinstance(exc, MissingExtraError):
        return str(exc)
    extra = EXTRA_OF.get((exc.name or "").split(".")[0])
    return message(extra) if extra else None


def message(extra: str, what: str | None = None) -> str:
    """``needs the 'tui' extra: pip install -e '.[tui]' in the project's clone`` (``what``
    first when given): the project is installed from its clone, not from PyPI."""
    head = f"{what}: " if what else ""
    line = f"{head}needs the {extra!r} extra: pip install -e '.[{extra}]' in the project's clone"
    if extra in ON_THE_ROBOT:
        line += f" (on the robot: apt-get install {ON_THE_ROBOT[extra]})"
    return line


def require(module: str, what: str | None = None) -> ModuleType:
    """Import ``module`` (an optional package), or raise :class:`MissingExtraError` naming the
    extra that installs it. ``what`` names the feature for the message (``"ball play"``)."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        top = module.split(".")[0]
        if (exc.name or "").split(".")[0] != top or top not in EXTRA_OF:
            raise
        raise MissingExtraError(module, EXTRA_OF[top], what) from None


class LazyModule:
    """An optional module imported at its first use, so that importing the code that uses it
    (the daemon's camera and vision modules) never needs it: ``cv2 = LazyModule("cv2",
    "the camera")`` at the top of a module, then ``cv2.imencode(…)`` as usual. ``load()``
    imports it now (to fail early, before a feature starts)."""

    def __init__(self, module: str, what: str | None = None) -> None:
        self._module = module
        self._what = what

    def load(self) -> ModuleType:
        return require(self._module, self._what)

    def __getattr__(self, name: str) -> Any:
        value = getattr(self.load(), name)
        self.__dict__[name] = value  # later uses are a plain attribute read
        return value
