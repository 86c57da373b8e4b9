"""Messages → pandas DataFrames and JPEG → numpy, for notebooks and recordings.

One row per message, flat columns (easy to plot, filter and export):

* ``joints``: ``stamp``, ``tick``, then ``<field>_<joint name>`` for every per-joint field
  (``position_r_knee`` in radians, ``goal_…``, ``velocity_…``, ``load_…``,
  ``temperature_…``, ``voltage_…``, ``torque_enabled_…``, ``online_…``, ``alarm_…``);
* vectors of three (``gyro``, ``accel``…) become ``gyro_x``, ``gyro_y``, ``gyro_z``;
* maps become ``<key>_<subkey>`` (``lease_name``, ``robot_x``…);
* ``camera`` keeps ``jpeg`` as bytes (decode with :func:`decode_jpeg`).

The index ``t`` is seconds since the first row's ``stamp``.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import numpy as np

from schemas.extras import LazyModule, require
from schemas.messages import Joints, Message

if TYPE_CHECKING:
    import pandas

pd = LazyModule("pandas", "DataFrames")

_AXES = ("x", "y", "z")
_SKIP = {"v", "type"}


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(f"{prefix}_{k}" if prefix else str(k), v, out)
    elif (
        isinstance(value, list)
        and len(value) == 3
        and all(isinstance(v, int | float) for v in value)
    ):
        for axis, v in zip(_AXES, value, strict=True):
            out[f"{prefix}_{axis}"] = v
    else:
        out[prefix] = value


def joints_row(msg: Joints) -> dict[str, Any]:
    row: dict[str, Any] = {"stamp": msg.stamp, "tick": msg.tick}
    for col in Joints.COLUMNS:
        if col in {"id", "name"}:
            continue
        for name, v in zip(msg.name, getattr(msg, col), strict=False):
            row[f"{col}_{name}"] = v
    return row


def row(msg: Message) -> dict[str, Any]:
    """One message as a flat dict of columns."""
    if isinstance(msg, Joints):
        return joints_row(msg)
    out: dict[str, Any] = {}
    for k, v in msg.to_dict().items():
        if k not in _SKIP:
            _flatten(k, v, out)
    return out


def to_frame(topic: str, messages: Iterable[Message]) -> pandas.DataFrame:
    """A DataFrame with one row per message (see the module docstring for the columns)."""
    rows = [row(m) for m in messages]
    df = pd.DataFrame(rows)
    if df.empty:
        return df.rename_axis("t")
    if "stamp" in df:
        df.index = pd.Index(df["stamp"] - df["stamp"].iloc[0], name="t")
    df.attrs["topic"] = topic
    return df


def joint_columns(df: pandas.DataFrame, field: str = "position") -> pandas.DataFrame:
    """The ``<field>_<joint>`` columns of a joints frame, renamed to the joint names."""
    prefix = f"{field}_"
    names = [c for c in df.columns if c.startswith(prefix)]
    return df[names].rename(columns=lambda c: c[len(prefix) :])


def decode_jpeg(data: bytes) -> np.ndarray:
    """JPEG bytes → RGB uint8 array (height × width × 3)."""
    cv2 = require("cv2", "decoding camera images")

    bgr = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if bgr is None:
        raise ValueError(f"camera frame of {len(data)} bytes is not a decodable JPEG")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
