"""What the doctor judges, gathered one of two ways: from the running daemon over Zenoh
(read-only: its status, joints and register reads) or, with the port free, by scanning the bus
directly (the same identify/describe as ``darwin scan``)."""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from typing import Any

from robot_daemon.bus.dxl import DxlBus, ReplyBudget
from robot_daemon.bus.port import BlockingPortHandler
from robot_daemon.bus.scan import describe
from robot_daemon.bus.tables import CM730, CM730_ID, MX28, STANDARD_BAUDS
from robot_daemon.doctor.checks import ServoInfo
from robot_daemon.doctor.daemon_link import DaemonLink
from schemas.errors import BusError, DarwinError
from schemas.messages import Joints, Status


@dataclass
class Facts:
    """What the probe gathered, from the daemon or the bus, for the checks to judge."""

    source: str  # "daemon" or "bus"
    answered_at: int | None = None
    devices: int = 0
    servos: dict[int, ServoInfo] = field(default_factory=dict)
    temperatures: dict[int, float] = field(default_factory=dict)
    voltage: float | None = None
    loop: dict[str, Any] | None = None
    state: str | None = None
    daemon_stamp: float | None = None
    daemon_version: str | None = None
    port: str = ""


def from_daemon(link: DaemonLink, ids: list[int], timeout: float = 3.0) -> Facts:
    """Facts from a running daemon (nothing is commanded)."""
    status = link.latest(Status, timeout)
    joints = link.latest(Joints, timeout)
    facts = Facts("daemon", state=status.state, port=str(status.bus.get("port", "")))
    facts.voltage = status.voltage or None
    facts.loop = dict(status.loop)
    facts.daemon_stamp = status.stamp
    facts.daemon_version = getattr(status, "version", None)
    facts.answered_at = None  # the daemon's bus runs: the configured rate, by construction
    for i, jid in enumerate(joints.id):
        if jid not in ids or not joints.online[i]:
            continue
        firmware = None
        with contextlib.suppress(DarwinError):  # an observer may not read registers
            firmware = link.registers(jid, MX28.FIRMWARE_VERSION.reg.address, 1)["data"][0]
        facts.servos[jid] = ServoInfo(jid, "MX-28", firmware)
        facts.temperatures[jid] = float(joints.temperature[i])
    facts.devices = len(facts.servos) + (1 if status.bus.get("cm730_online") else 0)
    return facts


def _answering_baud(
    handler: BlockingPortHandler, bus: DxlBus, baud: int, ids: list[int]
) -> int | None:
    """The first standard rate at which the CM-730 or any of ``ids`` answers a ping."""
    for rate in (baud, *(b for b in STANDARD_BAUDS if b != baud)):
        handler.setBaudRate(rate)
        if any(bus.ping(i) for i in (CM730_ID, *ids)):
            handler.setBaudRate(baud)
            return rate
    handler.setBaudRate(baud)
    return None


def from_bus(
    port: str,
    baud: int,
    ids: list[int],
    tries: int = 3,
    margin_ms: float = 20.0,
    power_on_s: float = 0.3,
) -> Facts:
    """Facts from the bus itself. Raises ``PortError`` when the port cannot be opened."""
    facts = Facts("bus", port=port)
    handler = BlockingPortHandler(port)
    handler.open(baud)
    try:
        bus = DxlBus(handler, ReplyBudget(margin_ms))
        try:
            bus.write(CM730_ID, CM730.DXL_POWER.reg.address, b"\x01", tries=tries)
            handler.pause(power_on_s)
        except BusError:
            pass  # judged below: nothing at this rate, or no CM-730
        facts.answered_at = _answering_baud(handler, bus, baud, ids)
        if facts.answered_at != baud:
            return facts
        cm = describe(bus, CM730_ID, tries)
        if cm is not None:
            facts.devices += 1
            facts.voltage = cm.get("voltage")
        for dxl_id in ids:
            info = describe(bus, dxl_id, tries)
            if info is None:
                continue
            facts.devices += 1
            facts.servos[dxl_id] = ServoInfo(dxl_id, info["model"], info["firmware"])
            if "temperature" in info:
                facts.temperatures[dxl_id] = float(info["temperature"])
    finally:
        handler.close()
    return facts
