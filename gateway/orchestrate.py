"""Orchestrate: a legacy list of behaviours played through the ``choreography`` verb.

The meaning of ``type`` comes from the daemon's ``behaviours`` verb (the project's behaviour
library and its legacy type table), fetched once and again whenever a list names a type or a
behaviour it does not know; it is never duplicated here. An item ``{"page": P, "type": T}``:

- ``T`` names an action kind and ``P`` is no behaviour id: action page ``P``;
- ``T`` is the generic ``behaviour`` type: behaviour ``P`` whatever its kind;
- otherwise behaviour ``P``, which must be of ``T``'s kind.

``{"time": S}`` sets the duration of the most recent walking item before it that has none yet,
or, when there is none, walks forward (the library's first straight forward walk) for ``S`` s.

The client gets ``{"orchestrate":{"status":1}}`` when the list starts and
``{"orchestrate":{"status":0}}`` when it ends: finished, stopped, replaced by another list or
halted. The end is seen on the daemon's ``choreography`` events, and on its status in case an
event was lost.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from gateway.messages import MessageError, Orchestrate, PlayItem, TimeItem, status_message
from gateway.translate import Command, orchestrate_stop_command
from schemas.errors import ErrorCode
from schemas.messages import Event, Status

if TYPE_CHECKING:
    from gateway.connection import Connection
    from gateway.server import Gateway

log = logging.getLogger(__name__)

GENERIC_TYPE = "behaviour"  # the type whose items may be of any kind
ENDED = {"finished", "stopped"}


class BehaviourTable:
    """The ``behaviours`` verb's answer: the library and the legacy ``type`` table."""

    def __init__(self, applied: dict[str, Any]) -> None:
        self.types: dict[int, str] = {int(k): str(v) for k, v in applied.get("types", {}).items()}
        self.behaviours: dict[int, dict[str, Any]] = {
            int(b["id"]): b for b in applied.get("behaviours", []) if "id" in b
        }

    def describe(self) -> str:
        return ", ".join(f"{t} = {kind}" for t, kind in sorted(self.types.items()))

    def forward_walk(self) -> dict[str, Any] | None:
        for b in self.behaviours.values():
            if (
                b.get("kind") == "walk"
                and b.get("x", 0) > 0
                and not b.get("y")
                and not b.get("turn")
            ):
                return b
        return None

    def item(self, index: int, page: int, type_: int) -> tuple[dict[str, Any], str]:
        """The choreography item for ``{"page", "type"}`` and its kind."""
        where = f"orchestrate item {index}"
        kind = self.types.get(type_)
        if kind is None:
            raise MessageError(
                ErrorCode.UNKNOWN,
                f"{where}: type {type_} is unknown; the robot's types are {self.describe()} "
                "(docs/gateway.md, or the behaviours query)",
            )
        behaviour = self.behaviours.get(page)
        if kind == "action" and behaviour is None:
            return {"page": page}, "action"
        if behaviour is None:
            raise MessageError(
                ErrorCode.UNKNOWN,
                f"{where}: page {page} is not a behaviour id of the robot's library "
                "(see the behaviours query)",
            )
        if kind != GENERIC_TYPE and behaviour.get("kind") != kind:
            raise MessageError(
                ErrorCode.INVALID,
                f"{where}: behaviour {page} ({behaviour.get('name')}) is a "
                f"{behaviour.get('kind')}, not a {kind} (type {type_})",
            )
        return {"behaviour": page}, str(behaviour.get("kind"))


def choreography_items(req: Orchestrate, table: BehaviourTable) -> list[dict[str, Any]]:
    """The ``choreography`` verb's items for a legacy list; ``MessageError`` names a bad item."""
    items: list[dict[str, Any]] = []
    open_walk: dict[str, Any] | None = None  # the latest walking item still without a time
    for index, entry in enumerate(req.items):
        if isinstance(entry, TimeItem):
            if open_walk is not None:
                open_walk["duration"] = entry.seconds
                open_walk = None
                continue
            forward = table.forward_walk()
            if forward is None:
                raise MessageError(
                    ErrorCode.UNAVAILABLE,
                    f"orchestrate item {index}: time without a walking item before it means "
                    "'walk forward', and the robot's library has no forward walk",
                )
            items.append({"behaviour": int(forward["id"]), "duration": entry.seconds})
            continue
        assert isinstance(entry, PlayItem)
        item, kind = table.item(index, entry.page, entry.type)
        items.append(item)
        if kind == "walk":
            open_walk = item
    return items


@dataclass
class Run:
    """An ``orchestrate`` sequence that runs: whose it is and the daemon's run number."""

    conn: Connection
    run: int | None  # the daemon's run number, when the verb said it


class Orchestrator:
    """Plays legacy lists and tells each client when its list ends."""

    def __init__(self, gateway: Gateway) -> None:
        self.gw = gateway
        self._table: BehaviourTable | None = None
        self.runs: dict[Connection, Run] = {}
        self._listening = False

    def _listen(self) -> None:
        if not self._listening:
            self._listening = True
            self.gw.hub.add_event_listener(self.on_event)
            self.gw.hub.add_status_listener(self.on_status)

    async def table(self, refresh: bool = False) -> BehaviourTable:
        if self._table is None or refresh:
            applied = await self.gw.blocking(lambda: self.gw.hub.robot.command("behaviours"))
            self._table = BehaviourTable(applied)
        return self._table

    async def play(self, conn: Connection, req: Orchestrate) -> None:
        self._listen()
        try:
            items = choreography_items(req, await self.table())
        except MessageError:
            # The daemon's library may have changed since the table was fetched: ask again.
            items = choreography_items(req, await self.table(refresh=True))
        applied = await conn.run(Command("choreography", {"op": "play", "items": items}))
        if applied is None:
            return
        run = applied.get("run")
        previous = self.runs.pop(conn, None)
        if previous is not None and previous.run != run:
            conn.send(status_message("orchestrate", 0))  # replaced by this client's new list
        self.runs[conn] = Run(conn, run if isinstance(run, int) else None)
        conn.send(status_message("orchestrate", 1))

    async def stop(self, conn: Connection) -> None:
        # Forget the run first: its "stopped" event may beat the verb's reply, and the client
        # gets exactly one status 0, the stop's answer.
        run = self.runs.pop(conn, None)
        if await conn.run(orchestrate_stop_command()) is None:
            if run is not None:
                self.runs[conn] = run
            return
        conn.send(status_message("orchestrate", 0))

    def detach(self, conn: Connection) -> None:
        self.runs.pop(conn, None)

    def _ended(self, ended: Run) -> None:
        if self.runs.get(ended.conn) is ended:
            del self.runs[ended.conn]
            ended.conn.send(status_message("orchestrate", 0))

    def on_event(self, event: Event) -> None:
        if event.kind != "choreography" or not self.runs:
            return
        state, run = event.data.get("state"), event.data.get("run")
        for r in list(self.runs.values()):
            if r.run is None or not isinstance(run, int):
                done = state in ENDED
            else:
                # A later run starting means ours was replaced, even if it never began.
                done = (state in ENDED and run == r.run) or run > r.run
            if done:
                self._ended(r)

    def on_status(self, status: Status) -> None:
        if not self.runs:
            return
        chor = status.choreography or status.motion.get("choreography") or {}
        run, playing = chor.get("run"), chor.get("playing")
        if not isinstance(run, int) or playing is None:
            return
        for r in list(self.runs.values()):
            if r.run is not None and (run > r.run or (run == r.run and not playing)):
                self._ended(r)
