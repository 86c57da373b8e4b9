"""The one writer of the user config file: sets values in place and keeps everything else.

The user file is hand-written TOML (comments, order, other tables), so it is edited line by line
rather than re-serialised: a key inside a ``[table]`` header's block is replaced where it stands,
a missing key is added at the end of its block, a missing table at the end of the file. The
result is parsed again before it replaces the file (atomically), and every written value must read
back as written, so a file this writer cannot edit safely (the key set as a dotted key or an
inline table elsewhere) is refused with one line and left unchanged.
"""

from __future__ import annotations

import os
import re
import tempfile
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from config.loader import config_path, user_config_path
from schemas.errors import ConfigError

_HEADER = re.compile(r"^\s*\[\s*([^\[\]]+?)\s*\]\s*(#.*)?$")
_ANY_HEADER = re.compile(r"^\s*\[")


def target_path(path: str | os.PathLike[str] | None = None) -> Path:
    """The file a change is written to: the one the loader reads (``--config FILE``, else
    ``$DARWIN_CONFIG``, else the platform user file or the robot's ``/etc/darwin/config.toml``,
    whichever exists first), else a new platform user file."""
    return config_path(path) or user_config_path()


def _format(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    raise ConfigError(f"cannot write {value!r} to the user config (not a number or a string)")


def _norm(table: str) -> str:
    return ".".join(part.strip().strip('"') for part in table.split("."))


def _block(lines: list[str], table: str) -> tuple[int, int] | None:
    """Line index of ``[table]``'s header and the index where its block ends."""
    for i, line in enumerate(lines):
        m = _HEADER.match(line)
        if m and _norm(m.group(1)) == table:
            end = i + 1
            while end < len(lines) and not _ANY_HEADER.match(lines[end]):
                end += 1
            # Trailing blank lines belong to the gap before the next table.
            while end > i + 1 and not lines[end - 1].strip():
                end -= 1
            return i, end
    return None


def _set(lines: list[str], table: str, key: str, value: Any) -> None:
    text = f"{key} = {_format(value)}"
    block = _block(lines, table)
    if block is None:
        if lines and lines[-1].strip():
            lines.append("")
        lines += [f"[{table}]", text]
        return
    start, end = block
    pattern = re.compile(rf"^\s*{re.escape(key)}\s*=")
    for i in range(start + 1, end):
        if pattern.match(lines[i]):
            comment = re.search(r"\s+#.*$", lines[i].split("=", 1)[1])
            lines[i] = text + (comment.group(0) if comment else "")
            return
    lines.insert(end, text)


def _lookup(data: Mapping[str, Any], table: str, key: str) -> Any:
    node: Any = data
    for part in table.split("."):
        node = node.get(part, {}) if isinstance(node, Mapping) else {}
    return node.get(key) if isinstance(node, Mapping) else None


def set_values(
    changes: Mapping[tuple[str, str], Any], path: str | os.PathLike[str] | None = None
) -> Path:
    """Write ``{(table, key): value}`` into the user file (created if absent); returns its path."""
    target = target_path(path)
    try:
        original = target.read_text(encoding="utf-8") if target.exists() else ""
    except OSError as exc:
        raise ConfigError(f"cannot read the user config {target}: {exc.strerror}") from exc
    try:
        tomllib.loads(original)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"user config {target} is not valid TOML ({exc}); fix it first") from exc
    lines = original.splitlines()
    for (table, key), value in changes.items():
        _set(lines, table, key, value)
    text = "\n".join(lines) + "\n"
    try:
        parsed = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(
            f"user config {target}: its layout cannot be edited safely ({exc}); "
            "write the values by hand"
        ) from exc
    for (table, key), value in changes.items():
        got = _lookup(parsed, table, key)
        if got != value and not (isinstance(got, float) and abs(got - value) < 1e-6):
            raise ConfigError(
                f"user config {target}: [{table}] {key} is also set elsewhere in the file "
                "(a dotted key or an inline table); write it by hand"
            )
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent)
    except PermissionError as exc:
        raise ConfigError(
            f"cannot write the config {target}: permission denied; run the command as its "
            "owner (sudo for /etc/darwin), or pass --config FILE"
        ) from exc
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target


def set_joint_offsets(
    offsets_deg: Mapping[str, float], path: str | os.PathLike[str] | None = None
) -> Path:
    """``[robot.joints.<name>] offset_deg`` for every joint in ``offsets_deg``."""
    return set_values(
        {(f"robot.joints.{name}", "offset_deg"): float(deg) for name, deg in offsets_deg.items()},
        path,
    )
