"""The Actions tab's page editor: a page as a table (a row per step, a column per joint in
degrees), editing with undo, teach mode (limp joints, move them by hand, capture). The editing
model is :class:`clients.pages.PageEditor`; against the simulator the joint under the cursor can
be pushed "by hand" through the emulator's control API. The page list and the player around it
are :class:`clients.tui.tabs.actions.ActionsTab`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.screen import ModalScreen
from textual.widgets import DataTable, Input, Label

from clients.pages import (
    GROUPS,
    HEADER,
    JOINTS,
    LEGS,
    EditError,
    PageEditor,
    joints_of,
    step_pose,
    step_seconds,
)
from clients.tui.i18n import N_, _
from clients.tui.model import Model
from clients.tui.tabs.base import TabView, show_text

HAND_STEP_DEG = 3.0  # one push "by hand" in the simulator
_WORDS = {"shoulder": "sh", "pitch": "p", "roll": "r", "elbow": "el", "hip": "hp", "yaw": "y"}
_WORDS |= {"knee": "kn", "ankle": "an", "head": "hd", "tilt": "tilt", "pan": "pan"}


def short(joint: str) -> str:
    """A narrow column title: ``r_shoulder_pitch`` → ``r_sh_p``."""
    return "_".join(_WORDS.get(w, w) for w in joint.split("_"))


def limb_of(joint: str) -> str:
    """The group a joint belongs to: ``right_arm``, ``left_leg``, ``head``…"""
    return next(g for g in ("right_arm", "left_arm", "right_leg", "left_leg", "head")
                if joint in GROUPS[g])


@dataclass
class ActionsState:
    """What the tab is doing; kept in the model so a language switch (which composes the
    screen again) loses nothing."""

    listing: list[dict[str, Any]] = field(default_factory=list)
    requested: bool = False
    editor: PageEditor | None = None
    limp: list[str] = field(default_factory=list)  # joints this tab made limp (teach mode)
    row: int = 0
    column: int = 0
    warned: bool = False  # Esc with unsaved changes warned once


class ConfirmScreen(ModalScreen[bool]):
    DEFAULT_CSS = """
    ConfirmScreen { align: center middle; }
    ConfirmScreen > Vertical { width: 64; height: auto; border: thick $error; background: $surface;
        padding: 0 1; }
    """
    BINDINGS = [
        Binding("y", "answer(True)", N_("Yes")),
        Binding("n,escape", "answer(False)", N_("No")),
    ]

    def __init__(self, question: str) -> None:
        super().__init__()
        self.question = question

    def compose(self) -> ComposeResult:
        with Vertical():
            yield Label(self.question)
            yield Label(_("y: yes · n / Esc: no"))

    def action_answer(self, yes: bool) -> None:
        self.dismiss(yes)


class PageEditView(TabView):
    """The editing half of the Actions tab: a base class; :class:`ActionsTab` is the tab (its
    layout, its keys, the page list)."""

    def __init__(self, model: Model) -> None:
        super().__init__(model)
        if model.edits.actions is None:
            model.edits.actions = ActionsState()
        self.st: ActionsState = model.edits.actions
        self._typing = "value"  # what the input box edits: "value" or "field"

    @property
    def editor(self) -> PageEditor | None:
        return self.st.editor

    # -- drawing ---------------------------------------------------------------------------------
    def show_status(self) -> None:
        parts = []
        action: Mapping[str, Any] = (
            self.model.status.motion.get("action") if self.model.status else None
        ) or {}
        if action.get("playing"):
            parts.append(_("playing page {page} step {step}").format(
                page=action.get("page"), step=action.get("step")))
        if self.st.limp:
            parts.append(_("TEACH: limp {joints} (k captures, Esc: torque on)").format(
                joints=", ".join(short(j) for j in self.st.limp)))
        show_text(self.query_one("#actions-status", Label), "  ".join(parts))

    def show_page(self) -> None:
        editor = self.editor
        listing = self.query_one("#pages-list", DataTable)
        table = self.query_one("#page-table", DataTable)
        info = self.query_one("#actions-page-info", Label)
        listing.display = editor is None
        table.display = info.display = editor is not None
        if editor is None:
            return
        p = editor.page
        info.update(
            _("page {number} “{name}” · repeat {repeat} · speed {speed} · accel {accel} · "
              "next {next} · exit {exit}").format(**{k: p.get(k, "") for k in HEADER})
            + (" · " + _("unsaved") if editor.dirty else "")
        )
        table.clear(columns=True)
        table.add_column(_("step"), key="step", width=4)
        table.add_column(_("time"), key="time", width=4)
        table.add_column(_("pause"), key="pause", width=5)
        for j in JOINTS:
            # A limp joint's column is marked: its value is what capture will store.
            table.add_column(short(j) + ("*" if j in self.st.limp else ""), key=j, width=7)
        for i, step in enumerate(editor.steps):
            cells = [str(i + 1), str(step.get("time", 0)), str(step.get("pause", 0))]
            cells += [f"{step[j]:7.2f}" if j in step else "    ·" for j in JOINTS]
            table.add_row(*cells, key=str(i))
        if editor.steps:
            row = min(self.st.row, len(editor.steps) - 1)
            table.move_cursor(row=row, column=max(self.st.column, 1))

    # -- where the cursor is -------------------------------------------------------------------
    def on_data_table_cell_highlighted(self, event: DataTable.CellHighlighted) -> None:
        if event.data_table.id == "page-table":
            self.st.row, self.st.column = event.coordinate.row, event.coordinate.column

    def cursor_key(self) -> str:
        """``time``, ``pause``, a joint name, or ``step`` for the cursor's column."""
        keys = ["step", "time", "pause", *JOINTS]
        return keys[min(self.st.column, len(keys) - 1)]

    def cursor_joint(self) -> str | None:
        key = self.cursor_key()
        return key if key in JOINTS else None

    def _edit(self, change: Callable[[PageEditor], Any]) -> Any:
        editor = self.editor
        if editor is None:
            return None
        try:
            result = change(editor)
        except EditError as exc:
            self.notify_error(str(exc))
            return None
        self.show_page()
        return result

    def open(self, table: dict[str, Any]) -> None:
        self.st.editor = PageEditor(table)
        self.st.row, self.st.column = 0, 3
        self.show_page()
        self.focus_target().focus()


    # -- editing ---------------------------------------------------------------------------------
    def action_undo(self) -> None:
        if self._edit(lambda e: e.undo()) is False:
            self.app.notify(_("Nothing to undo."))

    def action_nudge(self, delta: int) -> None:
        key, k = self.cursor_key(), self.st.row
        if key in JOINTS:
            self._edit(lambda e: e.nudge(k, key, float(delta)))
        elif key in ("time", "pause"):
            value = int(self.editor.step(k).get(key, 0)) + delta if self.editor else 0
            self._edit(lambda e: e.set_time(k, **{key: max(0, min(255, value))}))

    def action_type(self, what: str) -> None:
        if self.editor is None:
            return
        box = self.query_one("#actions-input", Input)
        box.display = True
        box.value = ""
        box.placeholder = (
            _("field=value: name, number, repeat, speed, accel, next, exit, schedule")
            if what == "field"
            else _("{key} of step {step} (− for not driven)").format(
                key=self.cursor_key(), step=self.st.row + 1)
        )
        box.focus()
        self._typing = what

    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.input.display = False
        text = event.value.strip()
        what = self._typing
        if what == "field":
            key, _sep, value = text.partition("=")
            key, value = key.strip(), value.strip()
            typed: Any = value if key in ("name", "schedule") else _integer(value)
            if typed is None:
                self.notify_error(_("{key} needs a whole number").format(key=key))
            else:
                self._edit(lambda e: e.set_field(key, typed))
        else:
            key, k = self.cursor_key(), self.st.row
            if key in JOINTS:
                number = None if text in ("-", "−", "") else _float(text)
                if number is None and text not in ("-", "−", ""):
                    self.notify_error(_("Type a number of degrees, e.g. -12.5"))
                else:
                    self._edit(lambda e: e.set_value(k, key, number))
            elif key in ("time", "pause") and _integer(text) is not None:
                self._edit(lambda e: e.set_time(k, **{key: _integer(text)}))
        self.focus_target().focus()

    def action_insert(self) -> None:
        k = self.st.row + 1 if self.editor and self.editor.steps else 0
        if self._edit(lambda e: e.insert_step(k)) is not None:
            self.st.row = k
            self.show_page()

    def action_duplicate(self) -> None:
        k = self._edit(lambda e: e.duplicate_step(self.st.row))
        if k is not None:
            self.st.row = k
            self.show_page()

    def action_move(self, delta: int) -> None:
        k = self._edit(lambda e: e.move_step(self.st.row, delta))
        if k is not None:
            self.st.row = k
            self.show_page()

    def action_mirror(self, how: str) -> None:
        self._edit(lambda e: e.mirror(self.st.row, None if how == "swap" else how))

    def action_save(self) -> None:
        if self.editor is not None:
            self.send("pages", tag="put", op="put", page=self.editor.page)

    # -- teach mode ------------------------------------------------------------------------------
    def present(self) -> dict[str, float]:
        joints = self.model.joints
        if joints is None:
            return {}
        return {n: math.degrees(p) for n, p in zip(joints.name, joints.position, strict=False)}

    def torque_on(self) -> dict[str, bool]:
        joints = self.model.joints
        return dict(zip(joints.name, joints.torque_enabled, strict=False)) if joints else {}

    def action_limp(self, what: str) -> None:
        joint = self.cursor_joint()
        if what != "all" and joint is None:
            self.notify_error(_("Put the cursor on a joint's column first."))
            return
        if what == "all" or joint is None:
            names = joints_of("all")
        else:
            names = joints_of(joint if what == "joint" else limb_of(joint))
        holding = [j for j in names if j in LEGS and self.torque_on().get(j, True)]

        def go(yes: bool | None = True) -> None:
            if yes:
                self.st.limp = sorted(set(self.st.limp) | set(names), key=JOINTS.index)
                self.send("torque", tag="limp", enable=False, ids=names)
                self.show_status()
                self.show_page()

        if holding:
            self.app.push_screen(
                ConfirmScreen(_("The legs hold the robot up: limp, it falls. Is it supported "
                                "(lying down, held, on a stand)?")),
                go,
            )
        else:
            go()

    def end_teach(self) -> None:
        if self.st.limp:
            self.send("torque", tag="stiffen", enable=True, ids=list(self.st.limp))
        self.st.limp = []
        self.show_status()
        self.show_page()

    def action_capture(self) -> None:
        present = self.present()
        if self.editor is None or not present:
            self.notify_error(_("Open a page (and wait for joint data) to capture a pose."))
            return
        if not self.editor.steps:
            self._edit(lambda e: e.insert_step(0, {}))
        chosen = list(self.st.limp) or None
        stored = self._edit(lambda e: e.capture(self.st.row, present, chosen))
        if stored is not None:
            self.app.notify(_("Captured {n} joints into step {step}.").format(
                n=len(stored), step=self.st.row + 1))
            self.end_teach()

    def action_by_hand(self, sign: int) -> None:
        """Push the cursor's joint as a hand would: the emulator's control API (simulator)."""
        # self.app is the DarwinApp, which holds the link.
        joint, robot = self.cursor_joint(), self.app.link.robot  # type: ignore[attr-defined]
        if joint is None or robot is None:
            return
        now = self.present().get(joint)
        if now is None:
            return
        jid = JOINTS.index(joint) + 1
        rad = math.radians(now + sign * HAND_STEP_DEG)

        def push() -> None:
            from schemas.sim_control import SimControl

            try:
                SimControl(robot.session, robot.target.robot, timeout=2.0).call(
                    "set_position", id=jid, rad=rad)
            except Exception as exc:
                self.app.call_from_thread(self.notify_error, _(
                    "Pushing by hand works against the simulator only: {error}").format(error=exc))

        self.run_worker(push, thread=True, exclusive=False)

    # -- robot -----------------------------------------------------------------------------------
    def action_go_step(self) -> None:
        if self.editor is None or not self.editor.steps:
            return
        step = self.editor.step(self.st.row)
        pose = step_pose(step)
        if pose:
            self.send(
                "pose",
                tag="pose",
                positions={j: math.radians(d) for j, d in pose.items()},
                duration=step_seconds(self.editor.page, step),
            )


def _integer(text: str) -> int | None:
    try:
        return int(text)
    except ValueError:
        return None


def _float(text: str) -> float | None:
    try:
        value = float(text.replace(",", "."))
    except ValueError:
        return None
    return value if math.isfinite(value) else None
