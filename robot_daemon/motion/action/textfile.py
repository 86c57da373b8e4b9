"""The project's readable action-page format (TOML), the twin of the ROBOTIS ``.bin``.

    [[page]]
    number = 15            # the page number (the stock numbers where the framework has one)
    name = "sit down"      # at most 14 characters
    repeat = 1             # times the page plays
    schedule = "time"      # "time" (0x0A) or "speed" (0x00)
    speed = 32             # 32 = real time; 64 plays twice as fast
    accel = 32             # ramp length of the trapezoidal profile, time units
    next = 0               # page chained after this one (0 = none)
    exit = 0               # page played instead of `next` when stopped (0 = none)

    [[page.step]]
    time = 125             # time units (8 ms at speed 32) to reach this key frame
    pause = 0              # time units to hold it
    r_shoulder_pitch = -48.34   # servo degrees (0 = raw 2048), joints by config name
    ...                         # a joint left out is not driven by this step

Only what the stock tool would not write by itself appears beyond that (``slopes``,
``reserved``, ``checksum``, ``name_tail``, per-step ``raw`` and ``spare``, and
``[[page.leftover]]`` steps stored after the step count), so that ``.bin`` → text → ``.bin`` is
byte-identical. Pages absent from a text file are blank.

A page may hold up to :data:`MAX_TEXT_STEPS` steps in text; the ``.bin`` holds 7, so writing a
longer page to a ``.bin`` is refused naming it. :func:`page_to_dict` and :func:`page_from_dict`
are the same table as a Python map (what the ``pages`` verb sends); errors name the field.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from config.loader import toml_file
from robot_daemon.motion.action.binfile import (
    DEFAULT_RESERVED,
    DEFAULT_SLOPES,
    DEFAULT_SPARE,
    JOINT_SLOTS,
    NAME_SIZE,
    NOT_DRIVEN,
    RESERVED_OFFSETS,
    SCHEDULE_SPEED,
    SCHEDULE_TIME,
    SLOPES_SIZE,
    SPARE_SLOTS,
    MotionFileError,
    Page,
    Step,
)
from schemas.units import POSITION_MAX, deg_to_raw, raw_to_deg

SCHEDULES = {"time": SCHEDULE_TIME, "speed": SCHEDULE_SPEED}
PAGE_KEYS = {
    "number",
    "name",
    "repeat",
    "schedule",
    "speed",
    "accel",
    "next",
    "exit",
    "step",
    "leftover",
    "slopes",
    "reserved",
    "checksum",
    "name_tail",
    "zero",
}
STEP_KEYS = {"time", "pause", "raw", "spare"}
MAX_TEXT_STEPS = 32  # a text page's steps (+ leftover); the .bin holds binfile.MAX_STEPS

HEADER = """\
# DARwIn-OP action pages, darwin-zenoh text format (docs/motion-files.md).
# time, pause: time units (8 ms at speed 32). Joints: servo degrees (0 = raw 2048);
# a joint left out of a step is not driven by it.
"""


def default_joint_names() -> dict[int, str]:
    from config.loader import load_robot

    robot = load_robot()
    return {j.id: j.name for j in robot.joints}


# -- writing -----------------------------------------------------------------------------------
def _step_lines(step: Step, table: str, names: dict[int, str]) -> list[str]:
    lines = [f"[[{table}]]"]
    for key, value in _step_dict(step, names).items():
        if key == "raw":
            lines.append("raw = { " + ", ".join(f"{k} = {v}" for k, v in value.items()) + " }")
        elif isinstance(value, float):
            # Two decimals round-trip exactly: a raw unit is 0.088°.
            lines.append(f"{key} = {value:.2f}")
        else:
            lines.append(f"{key} = {value}")
    return lines


def page_text(page: Page, names: dict[int, str]) -> str:
    if page.zero:
        return f"[[page]]\nnumber = {page.number}\nzero = true\n"
    schedule = next((k for k, v in SCHEDULES.items() if v == page.schedule), page.schedule)
    lines = [
        "[[page]]",
        f"number = {page.number}",
        f"name = {json.dumps(page.name)}",
        f"repeat = {page.repeat}",
        f"schedule = {json.dumps(schedule)}",
        f"speed = {page.speed}",
        f"accel = {page.accel}",
        f"next = {page.next}",
        f"exit = {page.exit}",
    ]
    if page.slopes != DEFAULT_SLOPES:
        lines.append(f'slopes = "{page.slopes.hex()}"')
    if page.reserved != DEFAULT_RESERVED:
        items = ", ".join(f"{k} = {v}" for k, v in sorted(page.reserved.items()))
        lines.append(f"reserved = {{ {items} }}" if items else "reserved = {}")
    if page.checksum is not None:
        lines.append(f"checksum = {page.checksum}")
    if page.name_tail:
        lines.append(f'name_tail = "{page.name_tail.hex()}"')
    for step in page.steps:
        lines += ["", *_step_lines(step, "page.step", names)]
    for step in page.leftover:
        lines += ["", *_step_lines(step, "page.leftover", names)]
    return "\n".join(lines) + "\n"


def _step_dict(step: Step, names: dict[int, str]) -> dict[str, Any]:
    out: dict[str, Any] = {"time": step.time, "pause": step.pause}
    raw: dict[str, int] = {}
    for slot in JOINT_SLOTS:
        word = step.words[slot]
        name = names.get(slot, f"joint{slot}")
        if word == NOT_DRIVEN:
            continue
        if word <= POSITION_MAX:
            out[name] = round(float(raw_to_deg(word)), 2)
        else:
            raw[name] = word
    if raw:
        out["raw"] = raw
    spare = tuple(step.words[s] for s in SPARE_SLOTS)
    if spare != DEFAULT_SPARE:
        out["spare"] = list(spare)
    return out


def page_to_dict(page: Page, names: dict[int, str] | None = None) -> dict[str, Any]:
    """The page as the table :func:`page_text` writes (what ``tomllib`` reads back from it)."""
    names = names or default_joint_names()
    if page.zero:
        return {"number": page.number, "zero": True}
    schedule = next((k for k, v in SCHEDULES.items() if v == page.schedule), page.schedule)
    out: dict[str, Any] = {
        "number": page.number,
        "name": page.name,
        "repeat": page.repeat,
        "schedule": schedule,
        "speed": page.speed,
        "accel": page.accel,
        "next": page.next,
        "exit": page.exit,
    }
    if page.slopes != DEFAULT_SLOPES:
        out["slopes"] = page.slopes.hex()
    if page.reserved != DEFAULT_RESERVED:
        out["reserved"] = {str(k): v for k, v in sorted(page.reserved.items())}
    if page.checksum is not None:
        out["checksum"] = page.checksum
    if page.name_tail:
        out["name_tail"] = page.name_tail.hex()
    out["step"] = [_step_dict(s, names) for s in page.steps]
    if page.leftover:
        out["leftover"] = [_step_dict(s, names) for s in page.leftover]
    return out


def dumps(pages: Iterable[Page], names: dict[int, str] | None = None) -> str:
    """Text for the pages worth writing (not the blank ones, not an all-zero page 0)."""
    names = names or default_joint_names()
    chunks = [HEADER]
    for page in sorted(pages, key=lambda p: p.number):
        if (page.number == 0 and page.zero) or page.blank:
            continue
        chunks.append(page_text(page, names))
    return "\n".join(chunks)


def write_text(path: str | Path, pages: Iterable[Page], names: dict[int, str] | None = None):
    Path(path).write_text(dumps(pages, names), encoding="utf-8")


# -- reading -----------------------------------------------------------------------------------
def _int(
    d: dict[str, Any],
    key: str,
    where: str,
    default: int,
    low: int = 0,
    high: int = 255,
    field: str | None = None,
) -> int:
    value = d.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise MotionFileError(
            f"{where}: {key} must be an integer {low}..{high}, got {value!r}", field or key
        )
    return value


def _parse_step(d: dict[str, Any], where: str, ids: dict[str, int], path: str = "step") -> Step:
    if not isinstance(d, dict):
        raise MotionFileError(f"{where}: a step must be a table", path)
    step = Step(
        time=_int(d, "time", where, 0, field=f"{path}.time"),
        pause=_int(d, "pause", where, 0, field=f"{path}.pause"),
    )
    for key, value in d.items():
        if key in STEP_KEYS:
            continue
        if key not in ids:
            raise MotionFileError(
                f"{where}: unknown joint {key!r}; joints are {', '.join(ids)}", f"{path}.{key}"
            )
        if isinstance(value, bool) or not isinstance(value, int | float) or value != value:
            raise MotionFileError(
                f"{where}: {key} must be degrees (a number), got {value!r}", f"{path}.{key}"
            )
        raw = deg_to_raw(float(value)) if abs(value) < 1e6 else -1
        if not 0 <= raw <= POSITION_MAX:
            raise MotionFileError(
                f"{where}: {key} = {value}° is outside the servo's range", f"{path}.{key}"
            )
        step.words[ids[key]] = raw
    raw_words = d.get("raw") or {}
    if not isinstance(raw_words, dict):
        raise MotionFileError(f"{where}: raw must be a table {{joint = word}}", f"{path}.raw")
    for key, value in raw_words.items():
        if key not in ids:
            raise MotionFileError(f"{where}: unknown joint {key!r} in raw", f"{path}.raw.{key}")
        step.words[ids[key]] = _int({key: value}, key, where, 0, 0, 0xFFFF, f"{path}.raw.{key}")
    spare = d.get("spare")
    if spare is not None:
        if not isinstance(spare, list) or len(spare) != len(SPARE_SLOTS):
            raise MotionFileError(
                f"{where}: spare must list {len(SPARE_SLOTS)} words", f"{path}.spare"
            )
        for slot, value in zip(SPARE_SLOTS, spare, strict=True):
            step.words[slot] = _int({"spare": value}, "spare", where, 0, 0, 0xFFFF, f"{path}.spare")
    return step


def _steps(d: dict[str, Any], key: str, where: str, ids: dict[str, int]) -> list[Step]:
    raw = d.get(key, [])
    if not isinstance(raw, list):
        raise MotionFileError(f"{where}: {key} must be a list of step tables", key)
    if len(raw) > MAX_TEXT_STEPS:
        raise MotionFileError(
            f"{where}: {len(raw)} steps; a page holds at most {MAX_TEXT_STEPS}", key
        )
    label = "step" if key == "step" else key
    return [
        _parse_step(s, f"{where}, {label} {i + 1}", ids, f"{key}[{i}]") for i, s in enumerate(raw)
    ]


def _parse_page(d: dict[str, Any], source: str, ids: dict[str, int]) -> Page:
    if not isinstance(d, dict):
        raise MotionFileError(f"{source}: a page must be a table", "page")
    number = d.get("number")
    if isinstance(number, bool) or not isinstance(number, int) or not 0 <= number <= 255:
        raise MotionFileError(f"{source}: a page needs a number 0..255, got {number!r}", "number")
    where = f"{source}, page {number}"
    unknown = set(d) - PAGE_KEYS
    if unknown:
        first = sorted(map(str, unknown))
        raise MotionFileError(f"{where}: unknown key(s) {', '.join(first)}", first[0])
    if d.get("zero"):
        return Page(number, zero=True)
    name = d.get("name", "")
    if not isinstance(name, str):
        raise MotionFileError(f"{where}: name must be a string, got {name!r}", "name")
    try:
        encoded = name.encode("latin-1")
    except UnicodeEncodeError:
        raise MotionFileError(
            f"{where}: name {name!r} has characters a page name cannot hold (Latin-1 only)",
            "name",
        ) from None
    if len(encoded) > NAME_SIZE:
        raise MotionFileError(
            f"{where}: name {name!r} is {len(encoded)} characters; at most {NAME_SIZE}", "name"
        )
    schedule = d.get("schedule", "time")
    schedule = SCHEDULES.get(schedule, schedule) if isinstance(schedule, str) else schedule
    if not isinstance(schedule, int) or isinstance(schedule, bool):
        raise MotionFileError(
            f"{where}: schedule must be 'time' or 'speed', got {schedule!r}", "schedule"
        )
    steps = _steps(d, "step", where, ids)
    leftover = _steps(d, "leftover", where, ids)
    if len(steps) + len(leftover) > MAX_TEXT_STEPS:
        raise MotionFileError(
            f"{where}: {len(steps)} steps; a page holds at most {MAX_TEXT_STEPS}", "step"
        )
    page = Page(
        number,
        name=name,
        repeat=_int(d, "repeat", where, 1),
        schedule=_int({"schedule": schedule}, "schedule", where, 0),
        speed=_int(d, "speed", where, 32, 1),
        accel=_int(d, "accel", where, 32),
        next=_int(d, "next", where, 0),
        exit=_int(d, "exit", where, 0),
        steps=steps,
        leftover=leftover,
    )
    if "slopes" in d:
        try:
            page.slopes = bytes.fromhex(d["slopes"])
        except (TypeError, ValueError):
            page.slopes = b""
        if len(page.slopes) != SLOPES_SIZE:
            raise MotionFileError(f"{where}: slopes must be {SLOPES_SIZE} bytes of hex", "slopes")
    if "reserved" in d:
        reserved = d["reserved"]
        if not isinstance(reserved, dict) or not all(
            str(k).isdigit() and int(k) in RESERVED_OFFSETS for k in reserved
        ):
            raise MotionFileError(
                f"{where}: reserved must map header offsets "
                f"({', '.join(map(str, RESERVED_OFFSETS))}) to bytes",
                "reserved",
            )
        page.reserved = {
            int(k): _int(reserved, k, where, 0, field=f"reserved.{k}") for k in reserved
        }
    if "checksum" in d:
        page.checksum = _int(d, "checksum", where, 0)
    if "name_tail" in d:
        try:
            page.name_tail = bytes.fromhex(d["name_tail"])
        except (TypeError, ValueError):
            raise MotionFileError(f"{where}: name_tail must be hex bytes", "name_tail") from None
        if len(encoded) + 1 + len(page.name_tail) > NAME_SIZE:
            raise MotionFileError(f"{where}: name_tail does not fit after the name", "name_tail")
    return page


def page_from_dict(
    d: dict[str, Any], names: dict[int, str] | None = None, source: str = "page"
) -> Page:
    """A page from its table (the ``pages`` verb's ``page``); errors name the field."""
    names = names or default_joint_names()
    return _parse_page(d, source, {name: jid for jid, name in names.items()})


def loads(text: str, source: str = "motion text", names: dict[int, str] | None = None):
    """Pages from text; raises :class:`MotionFileError` naming the file, page and field."""
    import tomllib  # here: the daemon reads its library through toml_file's kept copies

    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MotionFileError(f"{source} is not valid TOML: {exc}") from exc
    return _pages(doc, source, names)


def _pages(doc: dict[str, Any], source: str, names: dict[int, str] | None) -> list[Page]:
    names = names or default_joint_names()
    ids = {name: jid for jid, name in names.items()}
    unknown = set(doc) - {"page"}
    if unknown:
        raise MotionFileError(f"{source}: unknown top-level key(s) {', '.join(sorted(unknown))}")
    pages = [_parse_page(p, source, ids) for p in doc.get("page", [])]
    seen: set[int] = set()
    for p in pages:
        if p.number in seen:
            raise MotionFileError(f"{source}: page {p.number} appears twice")
        seen.add(p.number)
    return pages


def read_text(path: str | Path, names: dict[int, str] | None = None) -> list[Page]:
    p = Path(path)
    try:
        doc = toml_file(p, universal_newlines=True)  # parsed once, not at every start
    except OSError as exc:
        raise MotionFileError(f"cannot read motion file {p}: {exc.strerror}") from exc
    except ValueError as exc:  # tomllib.TOMLDecodeError, or text that is not UTF-8 as TOML is
        raise MotionFileError(f"{p} is not valid TOML: {exc}") from exc
    return _pages(doc, str(p), names)
