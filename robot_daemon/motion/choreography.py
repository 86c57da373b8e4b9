"""The choreography runner: plays a list of behaviours item by item.

It owns no joints: it drives the action, walking and head modules and the sound player, and
writes LEDs through a callable injected by the arbiter (motion never touches the bus). Each item
and the whole list publish ``started``/``finished`` on events and in status. ``stop`` ends the
current item as soon as it is safe (a walk finishes its step, an action brakes to the key frame
of its step) and skips the rest; ``halt`` ends it at once.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import Any

from robot_daemon.frames import JointFrame
from robot_daemon.motion.behaviours import BehaviourLibrary, Item
from robot_daemon.motion.interface import MotionModule
from robot_daemon.motion.sound import SoundPlayer
from schemas.units import rgb_to_color_word

LedWriter = Callable[[int | None, int | None], None]  # (head word, eye word)
HEAD_TIMEOUT = 3.0  # s: a head move that has not arrived by then counts as done

_runs = itertools.count(1)


class ChoreographyModule(MotionModule):
    name = "choreography"

    def __init__(self, sound: SoundPlayer | None = None) -> None:
        super().__init__()
        self.sound = sound or SoundPlayer()
        self.led_writer: LedWriter | None = None
        self.items: list[Item] = []
        self.index = -1
        self.run = 0
        self._pending: list[Item] | None = None
        self._state = "idle"  # idle | running | stopping
        self._item_started = False
        self._t0 = 0.0
        self.last_result: str | None = None
        self.behaviours: BehaviourLibrary = BehaviourLibrary(None)

    @property
    def active(self) -> bool:  # owns no joints, yet has to hear stop_all()
        return self.playing

    @property
    def sequencing(self) -> bool:
        return self.playing

    @property
    def playing(self) -> bool:
        return self._state != "idle" or self._pending is not None

    # -- commands -------------------------------------------------------------------------------
    def play(self, items: list[Item]) -> int:
        """Queue a list (checked by the caller); a list already playing is stopped first."""
        if not items:
            raise ValueError("a choreography needs at least one item")
        if self._state != "idle":
            self._end("stopped", "replaced by a new choreography")
        self._pending = list(items)
        self.run = next(_runs)
        return self.run

    def stop(self) -> None:
        if self._pending is not None:
            self._pending = None
        if self._state == "running":
            self._state = "stopping"
            self._stop_current()

    def halt(self) -> None:
        self._pending = None
        if self._state != "idle":
            self._end("stopped", "halted")

    # -- the tick -------------------------------------------------------------------------------
    def observe(self, frame: JointFrame) -> None:
        if self._pending is not None:
            self.items, self._pending = self._pending, None
            self.index, self._state = 0, "running"
            self._item_started = False
            self.emit(
                "choreography",
                f"choreography {self.run} started ({len(self.items)} items)",
                state="started",
                run=self.run,
                count=len(self.items),
            )
        if self._state == "idle":
            return
        while self._state != "idle":
            if not self._item_started:
                if self._state == "stopping":
                    self._end("stopped", "stopped on request")
                    return
                self._start_item(frame)
                if self._state == "idle":
                    return
            if not self._item_done(frame):
                return
            self._finish_item()

    def _module(self, name: str) -> Any:
        return self.manager.get(name) if self.manager is not None else None

    def _emit_item(self, item: Item, what: str) -> None:
        self.emit(
            "choreography",
            f"item {self.index + 1}/{len(self.items)} {what}: {item.label}",
            state=f"item_{what}",
            run=self.run,
            index=self.index,
            label=item.label,
            item_kind=item.kind,
        )

    def _start_item(self, frame: JointFrame) -> None:
        item = self.items[self.index]
        self._item_started, self._t0 = True, frame.time
        self._emit_item(item, "started")
        p = item.params
        try:
            if item.kind == "action":
                self._module("action").play(p["page"])
                if p.get("say") or p.get("file"):
                    self.sound.play(self.emit, file=p.get("file"), say=p.get("say"))
            elif item.kind == "walk":
                self._module("walking").start(p["x"], p["y"], p["turn"])
            elif item.kind == "sound":
                self.sound.play(self.emit, file=p.get("file"), say=p.get("say"))
            elif item.kind == "led":
                self._leds(p.get("head"), p.get("eye"))
            elif item.kind == "head":
                self._module("head").move(p["pan"], p["tilt"])
        except (KeyError, ValueError, AttributeError) as exc:
            self._end("failed", f"item {self.index + 1} ({item.label}) failed: {exc}")

    def _leds(self, head: list[int] | None, eye: list[int] | None) -> None:
        hw = rgb_to_color_word(*head) if head else None
        ew = rgb_to_color_word(*eye) if eye else None
        if self.led_writer is None:
            raise ValueError("no LED writer: LEDs are set through the daemon's bus")
        self.led_writer(hw, ew)

    def _item_done(self, frame: JointFrame) -> bool:
        item = self.items[self.index]
        elapsed = frame.time - self._t0
        if item.kind == "action":
            return not self._module("action").playing
        if item.kind == "walk":
            walking = self._module("walking")
            if walking.ctrl_running and elapsed >= item.params["duration"]:
                walking.stop()
            return not walking.running
        if item.kind == "pause":
            return self._state == "stopping" or elapsed >= item.params["duration"]
        if item.kind == "head":
            return self._module("head").reached() or elapsed >= HEAD_TIMEOUT
        return True  # sound and LED items start and are done

    def _stop_current(self) -> None:
        if not self._item_started or self.index >= len(self.items):
            return
        kind = self.items[self.index].kind
        if kind == "walk":
            self._module("walking").stop()
        elif kind == "action":
            self._module("action").brake()

    def _finish_item(self) -> None:
        item = self.items[self.index]
        self._emit_item(item, "finished")
        self.index += 1
        self._item_started = False
        if self.index >= len(self.items):
            self._end("finished", "all items played")

    def _end(self, how: str, why: str) -> None:
        if self._state == "running" or self._state == "stopping":
            if how != "finished" and self._item_started:
                self._stop_current()
            self.emit(
                "choreography",
                f"choreography {self.run} {how}: {why}",
                state=how,
                run=self.run,
                index=self.index,
                count=len(self.items),
            )
        self._state, self.last_result = "idle", how
        self._item_started = False

    def status(self) -> dict[str, Any]:
        current = self.items[self.index] if 0 <= self.index < len(self.items) else None
        return {
            "active": self.playing,
            "playing": self.playing,
            "run": self.run,
            "index": self.index if self.playing else None,
            "count": len(self.items),
            "item": current.label if current is not None and self.playing else None,
            "items": [i.label for i in self.items],
            "last_result": self.last_result,
        }
