"""Arbiter command payloads, one per verb under ``darwin/<robot>/cmd/<verb>``.

Every query payload is a msgpack map ``{"v": 1, "client": <client id>, ...fields}`` (build it
with :func:`schemas.messages.command_payload`), optionally with ``client_name`` (the caller's
human name, shown as the lease holder; ``name`` is a verb field, e.g. a joint's name).
Every reply is either
``{"v":1, "ok": true, "verb": v, "applied": {...}}`` sent with ``query.reply`` — *applied* says
what was actually applied after conversion — or ``{"v":1, "ok": false, "verb": v, "code": c,
"message": m, "field": f}`` sent with ``query.reply_err``; codes are :class:`ErrorCode`.
Angles are rad, speeds rad/s or m/s, durations s. Joints are named by id (1..20) or name.

| verb | fields | lease |
|---|---|---|
| lease | op: "acquire" \\| "release" \\| "status", name: str (human) | no |
| joint | id \\| name, position: rad, speed: rad/s (optional, 0 = servo max) | yes |
| pose | positions: {id-or-name: rad}, duration: s (> 0, interpolated) | yes |
| torque | enable: bool, ids: [id-or-name] (absent = all) | yes |
| led | head: [r,g,b] 0..255, eye: [r,g,b], panel: 0..7 (each optional, ≥ 1 present) | yes |
| halt | — (stop every motion module, hold the present pose) | never |
| config | — → joints, limits, offsets, tick period, walk params, robot name | no |
| registers | id, address, length (read) \\| id, address, data: [bytes] (write RAM) | write |
| action | op: "play" \\| "stop" \\| "brake", page: int \\| name: str \\| behaviour: id | play |
| walk | op: "start" \\| "set" \\| "stop", x: m/s, y: m/s, turn: rad/s | start/set |
| walk_params | set: {name: value} (absent = read) | set |
| head | pan: rad, tilt: rad \\| track: {pan_error, tilt_error} \\| op: "home" | yes |
| choreography | op: "play", items: [item…] \\| op: "stop" | play |
| sound | file: path \\| say: text | yes |
| playball | op: "start" \\| "stop", color: name (default "red") | start |
| behaviours | — → the behaviour library and the legacy ``type`` table | no |
| pages | op: list, get, put, delete, reload, export, play; number, page, step | put… |

A choreography item is ``{"behaviour": id, ...params}`` where params depend on the behaviour's
kind: ``action`` (page), ``walk`` (duration s, x, y, turn), ``sound`` (file/say), ``led``
(head/eye rgb), ``pause`` (duration s), ``head`` (pan, tilt). An item may also be
``{"kind": k, ...params}``, ``{"page": n}``, or a legacy orchestrate item ``{"page": P,
"type": T}`` / ``{"time": S}`` (the ``behaviours`` reply has the ``type`` table). ``choreography``
and ``sound`` take an optional ``lang``: "en" (default) or "pt". ``action`` may name the
page's ``name`` instead of its number; ``walk_params`` ``set`` values are the
``config/walking.toml`` names and units (README, "Motion").
"""

from __future__ import annotations

from enum import StrEnum


class LeaseOp(StrEnum):
    ACQUIRE = "acquire"
    RELEASE = "release"
    STATUS = "status"


class MotionOp(StrEnum):
    PLAY = "play"
    START = "start"
    SET = "set"
    STOP = "stop"
    BRAKE = "brake"
    HOME = "home"


# Verb → ops that are allowed without the lease (stopping is always allowed).
OPS_WITHOUT_LEASE: dict[str, frozenset[str]] = {
    "action": frozenset({"stop", "brake"}),
    "walk": frozenset({"stop"}),
    "choreography": frozenset({"stop"}),
    "playball": frozenset({"stop"}),
    "registers": frozenset({"read"}),
    "walk_params": frozenset({"read"}),
    "pages": frozenset({"list", "get", "export"}),
}
