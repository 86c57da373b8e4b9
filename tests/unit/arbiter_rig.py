"""An in-process arbiter pipeline for unit tests: the real parse, field checks, lease and verb
handlers on a real motion manager, with a bus that records every call (the edge of the world:
no serial port here). Writes are kept in a register memory so read-backs see them."""

from __future__ import annotations

from typing import Any

from config.loader import load_all, robot_from_dict
from robot_daemon.arbiter.core import execute, parse_request
from robot_daemon.arbiter.lease import Lease
from robot_daemon.arbiter.registry import MotionContext
from robot_daemon.arbiter.verbs import load_all as load_verbs
from robot_daemon.motion.setup import build_manager
from schemas.messages import command_payload


class RecordingBus:
    """The verbs' bus interface, recording every call."""

    def __init__(self) -> None:
        self.writes: list[tuple[str, Any]] = []
        self.reads: list[tuple[int, int, int]] = []
        self.memory: dict[tuple[int, int], int] = {}

    def set_leds(self, head: int | None, eye: int | None, panel: int | None) -> None:
        self.writes.append(("leds", (head, eye, panel)))

    def set_torque(self, ids: list[int], enable: bool) -> None:
        self.writes.append(("torque", (list(ids), enable)))

    def read_registers(self, dxl_id: int, address: int, length: int) -> bytes:
        self.reads.append((dxl_id, address, length))
        return bytes(self.memory.get((dxl_id, address + i), 0) for i in range(length))

    def write_registers(self, dxl_id: int, address: int, data: bytes) -> None:
        self.writes.append(("registers", (dxl_id, address, bytes(data))))
        target = dxl_id
        if address <= 3 < address + len(data):  # an ID write: the device answers there now
            target = data[3 - address]
        for i, b in enumerate(data):
            self.memory[(target, address + i)] = b


class ArbiterRig:
    def __init__(self, **extras: Any) -> None:
        load_verbs()
        self.settings = load_all()
        self.robot = robot_from_dict(self.settings["robot"])
        self.manager = build_manager(self.robot, self.settings)
        self.bus = RecordingBus()
        self.lease = Lease(60.0, heartbeat_timeout=0.0)
        self.events: list[tuple[str, str, dict[str, Any]]] = []
        self.extras = dict(extras)

    def context(self) -> MotionContext:
        return MotionContext(
            robot=self.robot,
            manager=self.manager,
            bus=self.bus,  # type: ignore[arg-type]
            settings=self.settings,
            frame=None,
            emit=lambda kind, message, **data: self.events.append((kind, message, data)),
            lease=self.lease,
            extras=dict(self.extras),
        )

    def acquire(self, client: str = "c1") -> str:
        return self.lease.acquire(client, "tester").token

    def send(self, verb: str, client: str = "c1", **envelope_and_fields: Any) -> dict[str, Any]:
        """One command through the real pipeline (payload → checks → lease → handler)."""
        return self.send_payload(verb, command_payload(client, **envelope_and_fields))

    def send_payload(self, verb: str, payload: bytes) -> dict[str, Any]:
        return execute(parse_request(verb, payload), self.context(), self.lease)
