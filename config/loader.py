"""Load the shipped TOML files and merge user overrides on top.

A user file is one TOML file whose top-level tables are the shipped sections (``robot``,
``daemon``, ``zenoh``, ``imu``, ``walking``, ``behaviours``…); each value replaces the shipped one.
It is found, first match wins, at: the ``path`` argument (``--config FILE``), ``$DARWIN_CONFIG``,
``<platform config dir>/darwin/config.toml`` if it exists, ``/etc/darwin/config.toml`` (the robot's,
written by docs/robot.md's recipe and read by its boot service) if it exists. The commands that
change the file (``config.user_file``) write to the same one, so an import lands where the daemon
reads.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import functools
import importlib.util
import marshal
import math
import os
import sys
import types
import typing
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

from schemas.errors import ConfigError

CONFIG_DIR = Path(__file__).resolve().parent
ENV_CONFIG = "DARWIN_CONFIG"


# The robot's own file: one per robot, whoever runs the command (root's boot service, a user).
SYSTEM_CONFIG = Path("/etc/darwin/config.toml")


def user_config_path() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "darwin" / "config.toml"


def config_path(path: str | os.PathLike[str] | None = None) -> Path | None:
    """The user file read on top of the shipped config (None: none exists yet)."""
    if path:
        return Path(path)
    if os.environ.get(ENV_CONFIG):
        return Path(os.environ[ENV_CONFIG])
    for default in (user_config_path(), SYSTEM_CONFIG):
        if default.exists():
            return default
    return None


def toml_file(path: Path, universal_newlines: bool = False) -> dict[str, Any]:
    """``tomllib.load`` of ``path`` (of its text read with universal newlines, as
    ``Path.read_text`` does, if asked); a shipped file (under :data:`KEPT_UNDER`) is kept as
    Python keeps bytecode: marshalled in ``__pycache__`` (or under ``PYTHONPYCACHEPREFIX``)
    beside the file's size and modification time, written unless ``PYTHONDONTWRITEBYTECODE``.
    Every program reads the same shipped files at each start (the config's 16 in each of
    ``darwin up``'s four, the motion library in the daemon): parsing them cost about 15 ms of
    CPU for the config and 35 ms for the library; loading what was parsed, well under one.
    Each call returns objects of its own."""
    with path.open("rb") as f:
        st = os.fstat(f.fileno())
        stamp = (st.st_mtime_ns, st.st_size, universal_newlines)
        cache = _cache_path(path)
        if cache is not None:
            try:
                kept_stamp, kept = marshal.loads(cache.read_bytes())
                if kept_stamp == stamp and isinstance(kept, dict):
                    return kept
            except (OSError, ValueError, EOFError, TypeError):
                pass  # none yet, or unreadable: parsed again and rewritten
        text = f.read().decode()
    if universal_newlines:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    # Here, not at the top: a program whose files were parsed before starts without the parser.
    import tomllib

    data = tomllib.loads(text)
    if cache is not None and not sys.dont_write_bytecode:
        _keep(cache, stamp, data)
    return data


# Only the shipped files are kept: a user's file is read by few starts and may be one of many
# short-lived ones (every test writes its own), which would pile up in the cache.
KEPT_UNDER: tuple[Path, ...] = (CONFIG_DIR,)


def _cache_path(path: Path) -> Path | None:
    directory = _resolved(path.parent)
    if not any(directory.is_relative_to(root) for root in KEPT_UNDER):
        return None
    try:
        # ``NAME.toml`` as if it were ``NAME.toml.py``: no clash with a module ``NAME.py``.
        pyc = Path(importlib.util.cache_from_source(f"{directory / path.name}.py"))
    except NotImplementedError:  # no cache tag in this interpreter
        return None
    return pyc.with_suffix(".marshal")


@cache
def _resolved(directory: Path) -> Path:
    # Once per directory: resolving each file (a system call per directory of its path) cost
    # half of reading the 35 shipped files' kept copies.
    return directory.resolve()


def _keep(cache: Path, stamp: tuple[int, int, bool], data: dict[str, Any]) -> None:
    try:
        blob = marshal.dumps((stamp, data))
    except ValueError:  # a TOML date or time, which marshal cannot hold: parsed every time
        return
    partial = cache.with_name(f"{cache.name}.{os.getpid()}.{id(blob)}.tmp")
    try:
        cache.parent.mkdir(parents=True, exist_ok=True)
        partial.write_bytes(blob)
        os.replace(partial, cache)  # whole or not at all, whoever else writes it
    except OSError:  # a read-only installation: parsed every time, as without the cache
        with contextlib.suppress(OSError):
            partial.unlink(missing_ok=True)


def _read_toml(path: Path) -> dict[str, Any]:
    try:
        return toml_file(path)
    except FileNotFoundError as exc:
        raise ConfigError(f"config file {path} does not exist") from exc
    except ValueError as exc:  # tomllib.TOMLDecodeError, or text that is not UTF-8 as TOML is
        raise ConfigError(f"config file {path} is not valid TOML: {exc}") from exc


def merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """Deep-merge ``over`` into a copy of ``base`` (tables merge, other values replace)."""
    out = copy.deepcopy(base)
    _merge_into(out, copy.deepcopy(over))
    return out


def _merge_into(out: dict[str, Any], over: dict[str, Any]) -> None:
    # ``over`` is handed over: its values are placed in ``out`` as they are, not copied.
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            _merge_into(out[k], v)
        else:
            out[k] = v


@cache
def _shipped() -> dict[str, Any]:
    # Each file's tables are freshly parsed and owned by nobody else: merged in place, where
    # copying the whole config so far at each of the 16 files cost every program of `darwin
    # up` about 10 ms of CPU at start.
    data: dict[str, Any] = {}
    for path in sorted(CONFIG_DIR.glob("*.toml")):
        _merge_into(data, _read_toml(path))
    return data


def shipped() -> dict[str, Any]:
    """The shipped config alone (no user file): e.g. before the first user file is written."""
    return copy.deepcopy(_shipped())


def load_all(path: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """Shipped config with the user file merged on top."""
    found = config_path(path)
    if found is not None:
        return merge(_shipped(), _read_toml(found))  # a copy already
    return copy.deepcopy(_shipped())


def load_section(name: str, path: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    data = load_all(path)
    if name not in data:
        raise ConfigError(f"no [{name}] section in the shipped config or {path or 'user file'}")
    return data[name]


# -- a config table → a settings dataclass ------------------------------------------------------
T = TypeVar("T", bound="DataclassInstance")


def nearest(name: str, known: Iterable[str], cutoff: float = 0.0) -> str | None:
    """The known name most like ``name`` (one differing only in case first), or None when
    none is at least ``cutoff`` alike (difflib's ratio, 0..1)."""
    known = list(known)
    by_lower = {k.lower(): k for k in known}
    if name.lower() in by_lower:
        return by_lower[name.lower()]
    # Here, not at the top: only a name nobody knows (an error) needs it, and every program of
    # `darwin up` imports this module at start.
    import difflib

    found = difflib.get_close_matches(name, known, n=1, cutoff=cutoff)
    return found[0] if found else None


def refuse_unknown(values: Mapping[str, Any], known: Iterable[str], where: str) -> None:
    """``ConfigError`` naming the first key of the table ``[where]`` that is not ``known``,
    and the known key nearest to it (a typo must not silently leave the default in force)."""
    known = list(known)
    for name in values:
        if name not in known:
            near = nearest(str(name), known)
            hint = f" (nearest known: {near!r})" if near else ""
            raise ConfigError(
                f"[{where}] has an unknown setting {name!r}{hint}; known: {', '.join(known)}"
            )


# Field metadata key of a setting's allowed range, (low, high), None for an open end.
RANGE = "range"


def ranged(default: Any, low: float | None = None, high: float | None = None) -> Any:
    """A settings field whose value must lie within ``low..high`` (None: no bound on that
    side); :func:`section_to` and :func:`check_ranges` refuse anything else, naming the field."""
    return field(default=default, metadata={RANGE: (low, high)})


def range_problem(value: float, low: float | None, high: float | None) -> str | None:
    """What ``value`` must be ("at least 1", "within 1..256") when outside ``low..high``."""
    if (low is None or value >= low) and (high is None or value <= high):
        return None
    if high is None:
        return f"at least {low:g}"
    if low is None:
        return f"at most {high:g}"
    return f"within {low:g}..{high:g}"


def check_ranges(settings: Any, where: str) -> None:
    """``ConfigError`` naming the first field of the dataclass ``settings`` (table ``[where]``)
    whose value lies outside the range it was declared with (:func:`ranged`)."""
    for f in dataclasses.fields(settings):
        if RANGE in f.metadata:
            value = getattr(settings, f.name)
            problem = range_problem(value, *f.metadata[RANGE])
            if problem:
                raise ConfigError(f"[{where}] {f.name} must be {problem}, not {value!r}")


def section_to(
    cls: type[T], values: Mapping[str, Any], where: str, skip: Iterable[str] = (), **given: Any
) -> T:
    """The dataclass ``cls`` from the config table ``[where]``.

    Every key must name a field (else ``ConfigError`` naming it and the nearest field), and
    each value must fit the field's type: bool, int, float (an integer is taken), str, a
    list for a tuple or list of those, a sub-table for a nested dataclass, and lie within the
    field's range if it has one (:func:`ranged`). Missing keys keep the defaults; a field
    without one must be there. ``given`` are fields the caller fills in (not read from the
    table); ``skip`` are keys of the table that another reader checks.
    """
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls) if f.init and f.name not in given]
    skipped = set(skip)
    table = {k: v for k, v in values.items() if k not in skipped}
    refuse_unknown(table, names, where)
    missing = [
        f.name
        for f in dataclasses.fields(cls)
        if f.name in names
        and f.name not in table
        and f.default is dataclasses.MISSING
        and f.default_factory is dataclasses.MISSING
    ]
    if missing:
        raise ConfigError(f"[{where}] is incomplete: it needs {', '.join(missing)}")
    out = dict(given)
    for name, value in table.items():
        try:
            out[name] = _convert(value, hints[name], f"{where}.{name}")
        except _Mismatch as exc:
            raise ConfigError(f"[{where}] {name} = {value!r} should be {exc}") from None
    settings = cls(**out)
    check_ranges(settings, where)
    return settings


class _Mismatch(Exception):
    """A value that does not fit a type; the message says what would."""


# What a value of each scalar type is called in an error: (one, several).
_SCALARS: dict[Any, tuple[str, str]] = {
    bool: ("true or false", "true/false values"),
    int: ("an integer", "integers"),
    float: ("a number", "numbers"),
    str: ("a string", "strings"),
}


def _describe(hint: Any) -> str:
    if hint in _SCALARS:
        return _SCALARS[hint][0]
    if dataclasses.is_dataclass(hint):
        return "a table"
    args = [a for a in typing.get_args(hint) if a is not type(None) and a is not Ellipsis]
    if typing.get_origin(hint) in (tuple, list):
        item = _SCALARS.get(args[0], ("", "values"))[1] if args else "values"
        fixed = typing.get_origin(hint) is tuple and Ellipsis not in typing.get_args(hint)
        return f"a list of {len(args)} {item}" if fixed and args else f"a list of {item}"
    return " or ".join(_describe(a) for a in args) or str(hint)


def _convert(value: Any, hint: Any, where: str) -> Any:
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if dataclasses.is_dataclass(hint):
        if not isinstance(value, dict):
            raise _Mismatch(_describe(hint))
        return section_to(typing.cast(type, hint), value, where)
    if origin in (typing.Union, types.UnionType):
        for arg in args:
            if arg is not type(None):  # TOML has no null: None is only ever the default
                try:
                    return _convert(value, arg, where)
                except _Mismatch:
                    pass
        raise _Mismatch(_describe(hint))
    if origin in (tuple, list):
        fixed = origin is tuple and bool(args) and args[-1] is not Ellipsis
        wanted = _describe(hint)
        if not isinstance(value, list | tuple) or (fixed and len(value) != len(args)):
            raise _Mismatch(wanted)
        kinds = args if fixed else [args[0] if args else Any] * len(value)
        try:
            return origin(_convert(v, k, where) for v, k in zip(value, kinds, strict=True))
        except _Mismatch:
            raise _Mismatch(wanted) from None
    if hint is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if hint in _SCALARS and (
        not isinstance(value, hint) or isinstance(value, bool) != (hint is bool)
    ):
        raise _Mismatch(_describe(hint))
    return value


@dataclass(frozen=True)
class JointConfig:
    """One joint of ``[robot]``: its servo ID, names, limits and calibration (degrees), and PID
    gains."""

    id: int
    name: str
    urdf: str
    min_deg: float
    max_deg: float
    offset_deg: float = 0.0
    direction: int = 1
    p: int = 32
    i: int = 0
    d: int = 0

    # Cached (a joint's limits never change): checked for every goal of every tick.
    @functools.cached_property
    def min_rad(self) -> float:
        return math.radians(self.min_deg)

    @functools.cached_property
    def max_rad(self) -> float:
        return math.radians(self.max_deg)

    def within(self, rad: float) -> bool:
        return self.min_rad - 1e-9 <= rad <= self.max_rad + 1e-9


@dataclass(frozen=True)
class RobotConfig:
    """The ``[robot]`` section: the robot's name, its CM-730 and joints, and lookups by ID and
    name."""

    name: str
    cm730_id: int
    joints: tuple[JointConfig, ...]
    max_speed: float = 5.65
    by_id: dict[int, JointConfig] = field(default_factory=dict, compare=False)
    by_name: dict[str, JointConfig] = field(default_factory=dict, compare=False)

    def joint(self, key: int | str) -> JointConfig:
        """Joint by id or name; ``KeyError`` with the known names otherwise."""
        found = self.by_id.get(key) if isinstance(key, int) else self.by_name.get(str(key))
        if found is None:
            raise KeyError(
                f"unknown joint {key!r}: ids are 1..20, names are {', '.join(self.by_name)}"
            )
        return found

    # Cached (the joints never change): the motion loop asks for them several times a tick.
    @functools.cached_property
    def ids(self) -> tuple[int, ...]:
        return tuple(j.id for j in self.joints)

    @functools.cached_property
    def names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)


def robot_from_dict(section: dict[str, Any]) -> RobotConfig:
    defaults = section.get("defaults", {})
    joints = []
    for name, j in section.get("joints", {}).items():
        merged = {**{k: v for k, v in defaults.items() if k != "max_speed"}, **j}
        try:
            jc = JointConfig(
                id=int(merged["id"]),
                name=name,
                urdf=str(merged.get("urdf", name)),
                min_deg=float(merged["min_deg"]),
                max_deg=float(merged["max_deg"]),
                offset_deg=float(merged.get("offset_deg", 0.0)),
                direction=int(merged.get("direction", 1)),
                p=int(merged.get("p", 32)),
                i=int(merged.get("i", 0)),
                d=int(merged.get("d", 0)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(
                f"joint {name!r} in [robot.joints] is incomplete or wrong: {exc}"
            ) from exc
        if jc.direction not in (1, -1):
            raise ConfigError(f"joint {name!r}: direction must be 1 or -1, not {jc.direction}")
        if jc.min_deg >= jc.max_deg:
            raise ConfigError(
                f"joint {name!r}: min_deg {jc.min_deg} is not below max_deg {jc.max_deg}"
            )
        joints.append(jc)
    joints.sort(key=lambda j: j.id)
    ids = [j.id for j in joints]
    if len(set(ids)) != len(ids):
        raise ConfigError(f"[robot.joints] repeats an id: {ids}")
    return RobotConfig(
        name=str(section.get("name", "op1")),
        cm730_id=int(section.get("cm730_id", 200)),
        joints=tuple(joints),
        max_speed=float(defaults.get("max_speed", 5.65)),
        by_id={j.id: j for j in joints},
        by_name={j.name: j for j in joints},
    )


def load_robot(path: str | os.PathLike[str] | None = None) -> RobotConfig:
    return robot_from_dict(load_section("robot", path))
