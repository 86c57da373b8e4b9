"""From Foxglove to the robot, through the arbiter and the lease, never around them.

Each Foxglove client gets its own :class:`~clients.commander.Commander` (its own client id and
liveliness token on the server's Zenoh session), so the lease is bound to the Foxglove client
that took it, exactly as for any other client; it is closed (and the arbiter releases its lease,
bringing motion to a safe stop) when that Foxglove client goes away.
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from clients.adapter_core import Action, AdapterCore
from clients.commander import Commander
from clients.robot import Robot
from schemas.errors import AdapterInputError, DarwinError

log = logging.getLogger(__name__)

TELEOP_SILENCE = 0.5  # s without a Teleop message stops a walk it started
MAX_REQUEST = 64 * 1024  # bytes of a service request or client message we decode at most


def parse_json(data: bytes, what: str) -> dict[str, Any]:
    if len(data) > MAX_REQUEST:
        raise AdapterInputError(f"{what}: {len(data)} bytes is more than the {MAX_REQUEST} allowed")
    if not data.strip():
        return {}
    try:
        value = json.loads(data)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise AdapterInputError(f"{what}: not JSON ({exc})") from None
    if not isinstance(value, dict):
        raise AdapterInputError(f"{what}: expected a JSON object, got {type(value).__name__}")
    return value


class Commanders:
    """One Commander per Foxglove client, sharing the server's Zenoh session."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self._lock = threading.Lock()
        self._by_client: dict[int, Commander] = {}

    def get(self, client_id: int) -> Commander:
        with self._lock:
            cmd = self._by_client.get(client_id)
            if cmd is None:
                cmd = Commander(
                    self.robot.target.endpoint,
                    self.robot.target.robot,
                    name=f"foxglove-{client_id}",
                    session=self.robot.session,
                    timeout=self.robot.timeout,
                )
                self._by_client[client_id] = cmd
            return cmd

    def drop(self, client_id: int) -> None:
        """The Foxglove client left: its token goes, so the arbiter ends its lease safely."""
        with self._lock:
            cmd = self._by_client.pop(client_id, None)
        if cmd is not None:
            cmd.close()

    def close(self) -> None:
        with self._lock:
            cmds = list(self._by_client.values())
            self._by_client.clear()
        for cmd in cmds:
            with contextlib.suppress(Exception):
                cmd.close()


# -- services ------------------------------------------------------------------------------------
def _halt(cmd: Commander, req: dict[str, Any]) -> dict[str, Any]:
    _only(req, set())
    return cmd.halt()


def _lease(cmd: Commander, req: dict[str, Any]) -> dict[str, Any]:
    _only(req, {"op"})
    op = req.get("op", "acquire")
    if op not in ("acquire", "release"):
        raise AdapterInputError(f"lease: op must be 'acquire' or 'release', not {op!r}")
    return cmd.acquire() if op == "acquire" else cmd.release()


def _action(cmd: Commander, req: dict[str, Any]) -> dict[str, Any]:
    _only(req, {"page", "name", "op"})
    if req.get("op") in ("stop", "brake"):
        return cmd.action_stop(brake=req["op"] == "brake")
    page = req.get("page", req.get("name"))
    if isinstance(page, bool) or not isinstance(page, int | str):
        raise AdapterInputError("action: give page (a number) or name (e.g. 'sit down')")
    return cmd.action(page)


def _behaviour(cmd: Commander, req: dict[str, Any]) -> dict[str, Any]:
    if req.get("op") == "stop":
        return cmd.choreography_stop()
    if "items" in req:
        _only(req, {"items"})
        if not isinstance(req["items"], list):
            raise AdapterInputError("behaviour: items must be a list of {behaviour: id, …}")
        return cmd.choreography(req["items"])
    if "behaviour" not in req:
        raise AdapterInputError("behaviour: give behaviour (an id or name) or items, or op=stop")
    return cmd.choreography([req])


def _torque(cmd: Commander, req: dict[str, Any]) -> dict[str, Any]:
    _only(req, {"enable", "ids"})
    enable = req.get("enable")
    if not isinstance(enable, bool):
        raise AdapterInputError("torque: enable must be true or false")
    ids = req.get("ids")
    if ids is not None and not isinstance(ids, list):
        raise AdapterInputError("torque: ids must be a list of joint ids or names")
    return cmd.torque(enable, ids)


def _only(req: dict[str, Any], allowed: set[str]) -> None:
    unknown = sorted(set(req) - allowed)
    if unknown:
        raise AdapterInputError(
            f"unknown field {unknown[0]!r}; allowed: {', '.join(sorted(allowed)) or 'none'}"
        )


def _obj(props: dict[str, Any]) -> dict[str, Any]:
    return {"type": "object", "properties": props, "additionalProperties": False}


# name → (handler, JSON schema of the request)
SERVICES: dict[str, tuple[Callable[[Commander, dict[str, Any]], dict[str, Any]], dict]] = {
    "/halt": (_halt, _obj({})),
    "/lease": (_lease, _obj({"op": {"type": "string", "enum": ["acquire", "release"]}})),
    "/action": (
        _action,
        _obj(
            {
                "page": {"type": "integer"},
                "name": {"type": "string"},
                "op": {"type": "string", "enum": ["stop", "brake"]},
            }
        ),
    ),
    "/behaviour": (
        _behaviour,
        {
            "type": "object",
            "properties": {
                "behaviour": {"type": ["integer", "string"]},
                "items": {"type": "array"},
                "op": {"type": "string", "enum": ["stop"]},
            },
        },
    ),
    "/torque": (
        _torque,
        _obj({"enable": {"type": "boolean"}, "ids": {"type": "array"}}),
    ),
}


def call_service(commanders: Commanders, name: str, client_id: int, payload: bytes) -> bytes:
    """Run one service call; the reply is ``{"ok": true, "applied": …}``. Refusals raise, and
    the SDK sends the message to the caller as a service call failure."""
    handler, _schema = SERVICES[name]
    req = parse_json(payload, name)
    try:
        applied = handler(commanders.get(client_id), req)
    except DarwinError as exc:
        raise RuntimeError(f"{name}: {exc}") from None
    return json.dumps({"ok": True, "applied": applied}, default=str).encode()


# -- teleop ----------------------------------------------------------------------------------
def twist_speeds(msg: dict[str, Any]) -> tuple[float, float, float]:
    """(x, y, turn) from a Twist-like map ``{linear: {x, y}, angular: {z}}``."""
    lin, ang = msg.get("linear", {}), msg.get("angular", {})
    if not isinstance(lin, dict) or not isinstance(ang, dict):
        raise AdapterInputError("teleop: expected {linear: {x, y, z}, angular: {x, y, z}}")
    out = []
    for part, key in ((lin, "x"), (lin, "y"), (ang, "z")):
        v = part.get(key, 0.0)
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise AdapterInputError(f"teleop: {key} must be a number, not {v!r}")
        out.append(float(v))
    return out[0], out[1], out[2]


def clamp(v: float, limit: float) -> float:
    return max(-limit, min(limit, v))


class Teleop:
    """Teleop messages → ``walk``; zero, or silence for TELEOP_SILENCE, stops the walk."""

    def __init__(self, commanders: Commanders, report: Callable[[str], None]) -> None:
        self.commanders = commanders
        self.report = report
        self._lock = threading.Lock()
        self._cores: dict[int, AdapterCore] = {}  # client → its deadman (one per client)
        self._limits: tuple[float, float, float] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="teleop-watchdog", daemon=True)
        self._thread.start()

    def limits(self, cmd: Commander) -> tuple[float, float, float]:
        if self._limits is None:
            m = cmd.command("walk_params").get("max_speed", {})
            self._limits = (float(m["x"]), float(m["y"]), float(m["turn"]))
        return self._limits

    def on_message(self, client_id: int, data: bytes) -> None:
        x, y, turn = twist_speeds(parse_json(data, "teleop"))
        cmd = self.commanders.get(client_id)
        try:
            if x == 0 and y == 0 and turn == 0:
                with self._lock:
                    core = self._cores.get(client_id)
                    was = core is not None and core.walk_stopped()
                if was:
                    cmd.walk_stop()
                return
            # A joystick asks for "as fast as it goes": clamp to the gait's limits rather than
            # refuse every message (the arbiter still checks what arrives).
            xm, ym, tm = self.limits(cmd)
            with self._lock:
                core = self._cores.setdefault(client_id, AdapterCore(deadman=TELEOP_SILENCE))
                core.walk(time.monotonic())
            cmd.walk(clamp(x, xm), clamp(y, ym), clamp(turn, tm))
        except DarwinError as exc:
            self.forget(client_id)
            self.report(f"teleop: {exc}")

    def forget(self, client_id: int) -> None:
        with self._lock:
            self._cores.pop(client_id, None)

    def _watch(self) -> None:
        while not self._stop.wait(0.1):
            now = time.monotonic()
            with self._lock:
                silent = [
                    c for c, core in self._cores.items() if Action.STOP_WALK in core.tick(now)
                ]
                for c in silent:
                    self._cores[c].walk_stopped()
            for c in silent:
                try:
                    self.commanders.get(c).walk_stop()
                except DarwinError as exc:
                    self.report(f"teleop: stopping after silence: {exc}")

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
