"""Load the shipped TOML files and merge user overrides on top.

A user file is one TOML file whose top-level tables are the shipped sections (``robot``,
``daemon``, ``zenoh``, ``imu``, ``walking``, ``behaviours``…); each value replaces the shipped one.
It is found, first match wins, at: the ``path`` argument (``--config FILE``), ``$DARWIN_CONFIG``,
``<platform config dir>/darwin/config.toml``.
"""

from __future__ import annotations

import copy
import math
import os
import tomllib
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

from schemas.errors import ConfigError

CONFIG_DIR = Path(__file__).resolve().parent
ENV_CONFIG = "DARWIN_CONFIG"


def user_config_path() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "darwin" / "config.toml"


def _read_toml(path: Path) -> dict[str, Any]:
    try:
        with path.open("rb") as f:
            return tomllib.load(f)
    except FileNotFoundError as exc:
        raise ConfigError(f"config file {path} does not exist") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"config file {path} is not valid TOML: {exc}") from exc


def merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """Deep-merge ``over`` into a copy of ``base`` (tables merge, other values replace)."""
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


@cache
def _shipped() -> dict[str, Any]:
    data: dict[str, Any] = {}
    for path in sorted(CONFIG_DIR.glob("*.toml")):
        data = merge(data, _read_toml(path))
    return data


def load_all(path: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """Shipped config with the user file merged on top."""
    data = _shipped()
    candidates: list[Path] = []
    if path:
        candidates.append(Path(path))
    elif os.environ.get(ENV_CONFIG):
        candidates.append(Path(os.environ[ENV_CONFIG]))
    else:
        default = user_config_path()
        if default.exists():
            candidates.append(default)
    for c in candidates:
        data = merge(data, _read_toml(c))
    return copy.deepcopy(data)


def load_section(name: str, path: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    data = load_all(path)
    if name not in data:
        raise ConfigError(f"no [{name}] section in the shipped config or {path or 'user file'}")
    return data[name]


@dataclass(frozen=True)
class JointConfig:
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

    @property
    def min_rad(self) -> float:
        return math.radians(self.min_deg)

    @property
    def max_rad(self) -> float:
        return math.radians(self.max_deg)

    def within(self, rad: float) -> bool:
        return self.min_rad - 1e-9 <= rad <= self.max_rad + 1e-9


@dataclass(frozen=True)
class RobotConfig:
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

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(j.id for j in self.joints)

    @property
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
