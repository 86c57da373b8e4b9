"""The ``Robot`` client's action-page and teach-mode methods: part of the notebook's one facade,
:class:`~clients.robot.Robot` (``Robot(Commander, TeachMixin)``).

    >>> with Robot() as robot, robot.control("teacher"):
    ...     page = robot.page_editor(200, "my wave")         # a new page (or an existing one)
    ...     robot.limp("right_arm")                          # move the arm by hand…
    ...     page.insert_step(0)
    ...     robot.capture(page, 0)                           # …store it; torque comes back
    ...     page.mirror(0, "right")                          # the left arm does the same
    ...     robot.page_put(page)                             # saved in the user's library
    ...     robot.page_play(200)

Editing itself is :class:`clients.pages.PageEditor` (pure, shared with the TUI). What this uses
of the Robot is declared with the Robot's own signatures (``command``, ``state``), so mypy checks
the two against each other where ``Robot`` joins them.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from clients.pages import LEGS, PageEditor, blank_page, joints_of, step_pose, step_seconds
from schemas.errors import ClientError, InvalidCommandError

if TYPE_CHECKING:
    from clients.robot import RobotState


class TeachMixin:
    """Uses ``command`` (:class:`~clients.commander.Commander`'s) and ``state`` (the Robot's
    latest messages) and nothing else of the Robot."""

    if TYPE_CHECKING:

        def command(
            self, verb: str, timeout: float | None = None, **fields: Any
        ) -> dict[str, Any]: ...

        @property
        def state(self) -> RobotState: ...

    # -- the library -----------------------------------------------------------------------------
    def pages(self) -> list[dict[str, Any]]:
        """Every page: number, name, steps, repeat, speed, next, exit, origin."""
        return self.command("pages", op="list")["pages"]

    def page(self, number: int) -> dict[str, Any]:
        """One page's table (what a TOML page file holds)."""
        return self.command("pages", op="get", number=number)["page"]

    def page_editor(self, number: int, name: str = "") -> PageEditor:
        """An editor on page ``number``: the library's page, or a new empty one."""
        try:
            table = self.page(number)
        except InvalidCommandError as exc:
            if exc.code != "unknown":
                raise
            table = blank_page(number, name)
        return PageEditor(table)

    def page_put(self, page: dict[str, Any] | PageEditor) -> dict[str, Any]:
        """Save a page in the user's motion library (needs the lease); the daemon uses it at
        once. A refusal names the field (``page.step[1].r_elbow``…)."""
        table = page.page if isinstance(page, PageEditor) else page
        applied = self.command("pages", op="put", page=table)
        if isinstance(page, PageEditor):
            page.dirty = False
        return applied

    def page_delete(self, number: int) -> dict[str, Any]:
        return self.command("pages", op="delete", number=number)

    def pages_reload(self) -> dict[str, Any]:
        """Read the library files again (after editing them by hand)."""
        return self.command("pages", op="reload")

    def pages_export(self, path: str | Path | None = None) -> bytes:
        """The whole library as a ROBOTIS ``motion_4096.bin`` (written to ``path`` if given)."""
        data = self.command("pages", op="export")["bin"]
        if path is not None:
            Path(path).write_bytes(data)
        return data

    def page_play(self, number: int, step: int = 1) -> dict[str, Any]:
        """Play a page from ``step`` (1-based); ``action_stop()`` stops or brakes it."""
        return self.command("pages", op="play", number=number, step=step)

    def step_pose(
        self, page: dict[str, Any] | PageEditor, step: int, duration: float | None = None
    ) -> dict[str, Any]:
        """Go to one step's pose (``step`` 1-based) in ``duration`` s (default: the step's
        time)."""
        table = page.page if isinstance(page, PageEditor) else page
        steps = table.get("step", [])
        if not 1 <= step <= len(steps):
            raise ClientError(f"page {table.get('number')} has steps 1..{len(steps)}")
        pose = step_pose(steps[step - 1])
        if not pose:
            raise ClientError(f"step {step} drives no joint")
        seconds = duration if duration is not None else step_seconds(table, steps[step - 1])
        return self.command(
            "pose", positions={j: math.radians(d) for j, d in pose.items()}, duration=seconds
        )

    # -- teach mode ------------------------------------------------------------------------------
    def _torque_map(self) -> dict[str, bool]:
        joints = self.state.joints
        if joints is None:
            raise ClientError("no joint state yet: wait for the first `joints` message")
        return dict(zip(joints.name, joints.torque_enabled, strict=False))

    def limp(self, joints: str | Iterable[str] = "all", confirm: bool = False) -> list[str]:
        """Torque off for a joint, a group (``right_arm``, ``left_leg``, ``head``, ``legs``,
        ``all``…) or a list, so they can be moved by hand. Legs that hold the robot up (torque
        on) go limp only with ``confirm=True``: the robot would fall."""
        names = joints_of(joints)
        holding = [j for j in names if j in LEGS and self._torque_map().get(j)]
        if holding and not confirm:
            raise ClientError(
                f"{', '.join(holding)} hold the robot up: making them limp drops it. Support "
                "the robot and call limp(..., confirm=True)"
            )
        self.command("torque", enable=False, ids=names)
        return names

    def stiffen(self, joints: str | Iterable[str] = "all") -> list[str]:
        """Torque back on (the servos hold where they are)."""
        names = joints_of(joints)
        self.command("torque", enable=True, ids=names)
        return names

    @contextlib.contextmanager
    def teaching(
        self, joints: str | Iterable[str] = "all", confirm: bool = False
    ) -> Iterator[list[str]]:
        """Joints limp inside the block, torque back on when it ends (even on error)."""
        names = self.limp(joints, confirm)
        try:
            yield names
        finally:
            with contextlib.suppress(Exception):
                self.stiffen(names)

    def limp_joints(self) -> list[str]:
        return [j for j, on in self._torque_map().items() if not on]

    def present_deg(self) -> dict[str, float]:
        joints = self.state.joints
        if joints is None:
            raise ClientError("no joint state yet: wait for the first `joints` message")
        return {n: math.degrees(p) for n, p in zip(joints.name, joints.position, strict=False)}

    def capture(
        self,
        page: PageEditor,
        step: int,
        joints: str | Iterable[str] | None = None,
        stiffen: bool = True,
    ) -> dict[str, float]:
        """Store the present angles in ``page``'s step ``step`` (0-based index): of ``joints``,
        else of the limp joints (all joints when none is limp). Torque comes back on for the
        limp ones unless ``stiffen`` is False. Returns what was stored (degrees)."""
        limp = self.limp_joints()
        names = joints_of(joints) if joints is not None else (limp or None)
        stored = page.capture(step, self.present_deg(), names)
        if stiffen and limp:
            self.command("torque", enable=True, ids=limp)
        return stored
