"""The rules a page must follow to be saved or played, and to fit a ROBOTIS ``.bin``.

The text parser already refuses what cannot be read (types, ranges of bytes, unknown joints,
name length); these are the rules that need the robot or the library: joint limits from config,
at least one step, a time of at least one unit, ``next``/``exit`` naming pages that exist.
Every problem names the field of the page table (``step[2].r_elbow``, ``next``…).
"""

from __future__ import annotations

import math
from collections.abc import Container, Iterable
from dataclasses import dataclass

from config.loader import RobotConfig
from robot_daemon.motion.action.binfile import JOINT_SLOTS, MAX_STEPS, Page
from schemas.units import raw_to_rad


@dataclass(frozen=True)
class Problem:
    """What is wrong with a page, and in which field."""

    field: str
    message: str

    def __str__(self) -> str:
        return self.message


def page_problems(page: Page, robot: RobotConfig, known: Container[int]) -> list[Problem]:
    """Why ``page`` may not be saved or played (empty when it may). ``known``: the page
    numbers ``next`` and ``exit`` may name (the page itself always counts)."""
    label = f"page {page.number} ({page.name})"
    out: list[Problem] = []
    if not 1 <= page.number <= 255:
        out.append(Problem("number", f"{label}: the number must be 1..255"))
    if not page.steps:
        out.append(Problem("step", f"{label}: a page needs at least one step"))
    for i, step in enumerate(page.steps):
        if step.time < 1:
            out.append(
                Problem(f"step[{i}].time", f"{label} step {i + 1}: time must be 1..255 units")
            )
    out += limit_problems(page, robot)
    for key in ("next", "exit"):
        target = getattr(page, key)
        if target and target != page.number and target not in known:
            out.append(Problem(key, f"{label}: {key} = {target} names no page in the library"))
    return out


def limit_problems(page: Page, robot: RobotConfig) -> list[Problem]:
    """Every step target of ``page`` outside the configured joint limits."""
    label = f"page {page.number} ({page.name})"
    out: list[Problem] = []
    for i, step in enumerate(page.steps):
        for jid in JOINT_SLOTS:
            if not step.driven(jid) or jid not in robot.by_id:
                continue
            joint = robot.by_id[jid]
            rad = float(raw_to_rad(step.words[jid]))
            if not joint.within(rad):
                out.append(
                    Problem(
                        f"step[{i}].{joint.name}",
                        f"{label} step {i + 1}: {joint.name} {math.degrees(rad):.1f}° is outside "
                        f"its limits {joint.min_deg:.0f}°..{joint.max_deg:.0f}°",
                    )
                )
    return out


def bin_problems(pages: Iterable[Page]) -> list[Problem]:
    """What a ROBOTIS ``.bin`` cannot hold (the text format can): more than 7 steps."""
    out = []
    for page in sorted(pages, key=lambda p: p.number):
        stored = len(page.steps) + len(page.leftover)
        if stored > MAX_STEPS:
            out.append(
                Problem(
                    "step",
                    f"page {page.number} ({page.name}) has {stored} steps; a ROBOTIS .bin page "
                    f"holds at most {MAX_STEPS}: split it into pages chained with next",
                )
            )
    return out
