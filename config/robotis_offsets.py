"""The offsets ROBOTIS's own offset tuner leaves on the robot, read from its ``config.ini``.

ROBOTIS's framework keeps them in the ``[Offset]`` section of ``/darwin/Data/config.ini``, one
key per servo ID, ``ID_01 = -12`` (``sprintf(key, "ID_%.2d", id)``), in servo steps of 4096 per
revolution; ``MotionManager::Process()`` adds ``m_Offset[id]`` to every goal it sync-writes
(``GetValue(id) + m_Offset[id]``; read in ``MotionManager::LoadINISettings``). The project's
``offset_deg`` is added to every goal in the same way (``servo = direction · joint + offset``,
:mod:`robot_daemon.bus.calibration`), so the value carries over with its sign:
``offset_deg = steps · 360 / 4096``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from config.loader import RobotConfig
from schemas import units
from schemas.errors import ConfigError

SECTION = "Offset"
# An offset this large is no calibration but a wrong file (ROBOTIS's tuner nudges by a few steps).
MAX_STEPS = 512
_SECTION = re.compile(r"^\s*\[\s*([^\]]*?)\s*\]")
_KEY = re.compile(r"^\s*([A-Za-z0-9_]+)\s*[=:]\s*([^;#]*)")
_ID_KEY = re.compile(r"^ID_(\d+)$", re.IGNORECASE)


@dataclass(frozen=True)
class ImportedOffsets:
    """The ``[Offset]`` section of a ROBOTIS ``config.ini``, read for one robot's joints."""

    steps: dict[int, int]  # servo ID → ROBOTIS steps
    degrees: dict[str, float]  # joint name → offset_deg
    ignored: list[str]  # keys of the section that name no joint of this robot


def read_offset_steps(text: str, where: str = "config.ini") -> dict[int, int]:
    """``{ID: steps}`` from the ``[Offset]`` section of a ROBOTIS ``config.ini`` (minIni format:
    ``;`` or ``#`` comments, section names case-insensitive)."""
    section: str | None = None
    found = False
    steps: dict[int, int] = {}
    for number, line in enumerate(text.splitlines(), 1):
        head = _SECTION.match(line)
        if head:
            section = head.group(1)
            found = found or section.lower() == SECTION.lower()
            continue
        if section is None or section.lower() != SECTION.lower():
            continue
        kv = _KEY.match(line)
        if not kv:
            continue
        key, raw = kv.group(1), kv.group(2).strip()
        m = _ID_KEY.match(key)
        if not m:
            raise ConfigError(f"{where} line {number}: [{SECTION}] key {key!r} is not ID_nn")
        try:
            value = int(raw)
        except ValueError:
            raise ConfigError(
                f"{where} line {number}: {key} = {raw!r} is not a whole number of steps"
            ) from None
        if abs(value) > MAX_STEPS:
            raise ConfigError(
                f"{where} line {number}: {key} = {value} steps is beyond ±{MAX_STEPS} "
                f"(±{MAX_STEPS * units.DEG_PER_UNIT:.0f}°); is this the robot's config.ini?"
            )
        steps[int(m.group(1))] = value
    if not found:
        raise ConfigError(f"{where} has no [{SECTION}] section (ROBOTIS's offset tuner writes it)")
    return steps


def import_offsets(path: str | Path, robot: RobotConfig) -> ImportedOffsets:
    """The joint offsets (degrees) of ROBOTIS's ``config.ini`` at ``path`` for ``robot``."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except FileNotFoundError:
        raise ConfigError(
            f"{p} does not exist; copy it from the robot (/darwin/Data/config.ini)"
        ) from None
    except OSError as exc:
        raise ConfigError(f"cannot read {p}: {exc.strerror}") from None
    steps = read_offset_steps(text, str(p))
    degrees: dict[str, float] = {}
    ignored: list[str] = []
    for dxl_id, value in sorted(steps.items()):
        joint = robot.by_id.get(dxl_id)
        if joint is None:
            ignored.append(f"ID_{dxl_id:02d}")
            continue
        degrees[joint.name] = value * units.DEG_PER_UNIT  # exact: a binary fraction
    return ImportedOffsets(steps, degrees, ignored)


# Where it is on a stock robot: ROBOTIS's programs read ``INI_FILE_PATH``, relative to their
# directory under /darwin/Linux/project (``"../../../Data/config.ini"`` from the demo's).
ROBOTIS_CONFIG_INI = "/darwin/Data/config.ini"


@dataclass(frozen=True)
class NotImported:
    """ROBOTIS's offsets on the robot that the daemon's config does not have: what, and the fix."""

    detail: str
    fix: str

    def line(self) -> str:
        return f"{self.detail}: {self.fix}"


def offsets_not_imported(path: str | Path, robot: RobotConfig) -> NotImported | None:
    """When ROBOTIS's ``config.ini`` at ``path`` calibrates joints that ``robot`` (the daemon's
    config) does not: a robot tuned with ROBOTIS's offset tuner whose offsets were never
    imported walks with every joint off by them. None when the file is absent or agrees."""
    p = Path(path)
    if not p.is_file():
        return None
    skip = 'or set [daemon] robotis_config_ini = "" to skip this check'
    try:
        imported = import_offsets(p, robot)
    except ConfigError as exc:
        return NotImported(f"ROBOTIS's offsets not checked: {exc}", f"fix or move {p}, {skip}")
    half_step = units.DEG_PER_UNIT / 2
    differ = {
        name: deg
        for name, deg in imported.degrees.items()
        if abs(deg - robot.joint(name).offset_deg) > half_step
    }
    if not differ:
        return None
    name, deg = max(differ.items(), key=lambda kv: abs(kv[1]))
    here = robot.joint(name).offset_deg
    return NotImported(
        f"{p} calibrates {len(differ)} joint(s) this config does not (e.g. {name}: {deg:+.2f}° "
        f"there, {here:+.2f}° here)",
        f"import them with `darwin calibrate import {p} --config FILE` (FILE: the config the "
        f"daemon reads; docs/calibration.md), {skip}",
    )
