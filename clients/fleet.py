"""Discovery of a fleet: which robots are live on the key space, and their state in one record.

One implementation, used by ``darwin list``, :meth:`clients.robot.Robot.discover` and the TUI's
connect screen. A robot is live while its daemon's ``darwin/<robot>/alive`` liveliness token
exists (it goes when the daemon stops, or within the link lease when it dies or its link does);
the rest of a record comes from the robot's ``status`` publication (~10 Hz): where it is reached
(``status.network.endpoint``: its router when it joined one), the lease holder, the battery
voltage, servo alarms and the motion loop's rate.
"""

from __future__ import annotations

import contextlib
import threading
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import zenoh

from schemas.errors import IncompatibleProtocolError, ProtocolError
from schemas.keys import every_robot, robot_of
from schemas.messages import AlarmInfo, Status, decode, decode_dict
from schemas.session import Credentials, connect
from schemas.versions import announcement, check_daemon, fmt

# How long discovery waits for each live robot's status (it arrives at ~10 Hz).
STATUS_WAIT_S = 2.0


@dataclass(frozen=True)
class RobotRecord:
    """One live robot, as ``darwin list`` shows it (``--json`` prints these fields)."""

    name: str
    endpoint: str = ""  # where clients reach it (its router's endpoint in a fleet)
    state: str = "unknown"  # the daemon's state; "unknown" when no status arrived in time
    lease_holder: str | None = None  # the holder's human name, None when nobody holds it
    battery: float | None = None  # supply voltage (V)
    alarms: list[AlarmInfo] = field(default_factory=list)  # servos with alarm bits set
    loop_hz: float | None = None  # the motion loop's rate (1 / median period)
    version: str = ""  # the daemon's package version
    protocol: str = ""  # the daemon's protocol, MAJOR.MINOR
    incompatible: str | None = None  # why this client cannot drive it (another protocol major)
    power: str = ""  # the battery policy's level (ok, warn, sit, off)
    hottest: list[dict[str, Any]] = field(default_factory=list)  # [{"id", "name", "celsius"}]
    loop_overloaded: bool = False  # sustained overruns: the computer cannot keep the loop

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def line(self) -> str:
        """``name: endpoint`` and the rest, one line (``darwin list``)."""
        lease = self.lease_holder or "free"
        battery = "?" if self.battery is None else f"{self.battery:.1f} V"
        alarms = ", ".join(f"id {a['id']} bits {a['bits']}" for a in self.alarms) or "none"
        rate = "?" if self.loop_hz is None else f"{self.loop_hz:.0f} Hz"
        if self.loop_overloaded:
            rate += " OVERLOADED"
        where = self.endpoint or "?"
        if self.incompatible:
            return f"{self.name}: {where}  (incompatible: {self.incompatible})"
        if self.power and self.power != "ok":
            battery += f" {self.power}"
        hot = ", ".join(f"{h['name']} {h['celsius']:.0f} °C" for h in self.hottest[:2])
        return (
            f"{self.name}: {where}  ({self.state}; lease {lease}; battery {battery}; "
            f"hottest {hot or '?'}; alarms {alarms}; loop {rate}; "
            f"daemon {self.version or '?'} protocol {self.protocol or '?'})"
        )


def record_from_status(
    name: str, status: Status | None, raw: dict[str, Any] | None = None
) -> RobotRecord:
    raw = raw or {}
    if status is None:
        protocol, version = announcement(raw)
        return RobotRecord(
            name,
            incompatible=raw.get("_incompatible"),
            version=version if raw else "",
            protocol=fmt(protocol) if raw else "",
        )
    protocol, version = announcement(raw or status.to_dict())
    lease = status.lease or None
    period = status.loop.get("period_p50_ms") or 0.0
    tick = status.loop.get("tick_ms") or 0.0
    loop_ms = period or tick
    return RobotRecord(
        name=name,
        endpoint=str(status.network.get("endpoint", "")),
        state=status.state,
        lease_holder=str(lease.get("name") or lease.get("client")) if lease else None,
        battery=float(status.voltage),
        alarms=list(status.alarms),
        loop_hz=round(1000.0 / loop_ms, 1) if loop_ms > 0 else None,
        version=version,
        protocol=fmt(protocol),
        power=str(status.power.get("level", "")),
        hottest=list(status.heat.get("hottest", [])),
        loop_overloaded=bool(status.loop.get("overloaded", False)),
    )


def live_robots(session: zenoh.Session, timeout: float = 2.0) -> list[str]:
    """Names of the robots whose ``alive`` token exists, sorted."""
    names = set()
    for reply in session.liveliness().get(every_robot().alive, timeout=timeout):
        if reply.ok is not None:
            with contextlib.suppress(ValueError):
                names.add(robot_of(str(reply.ok.key_expr)))
    return sorted(names)


def discover(
    session: zenoh.Session, timeout: float = STATUS_WAIT_S, pattern: str = "*"
) -> list[RobotRecord]:
    """Every live robot (matching ``pattern``, a robot name or ``*``) with its latest status,
    sorted by name; a robot whose status does not arrive within ``timeout`` is listed with what
    is known (its name, state ``unknown``)."""
    statuses: dict[str, Status | None] = {}
    raws: dict[str, dict[str, Any]] = {}
    cond = threading.Condition()

    def on_status(sample: zenoh.Sample) -> None:
        msg: Status | None = None
        try:
            name = robot_of(str(sample.key_expr))
            raw = decode_dict(sample.payload.to_bytes())
            check_daemon(raw, "darwin list")
            msg = decode(sample.payload.to_bytes(), Status)
        except IncompatibleProtocolError as exc:
            raw["_incompatible"] = str(exc)
        except (ProtocolError, ValueError):
            return  # a foreign publisher: not ours to list
        with cond:
            statuses[name] = msg
            raws[name] = raw
            cond.notify_all()

    # Subscribe first: a status published while the token query runs is not missed.
    sub = session.declare_subscriber(every_robot().status, on_status)
    try:
        names = [n for n in live_robots(session) if pattern in ("*", n)]
        deadline = time.monotonic() + timeout
        with cond:
            cond.wait_for(
                lambda: all(n in statuses for n in names), max(0.0, deadline - time.monotonic())
            )
            return [record_from_status(n, statuses.get(n), raws.get(n, {})) for n in names]
    finally:
        with contextlib.suppress(Exception):
            sub.undeclare()


def discover_at(
    endpoint: str,
    timeout: float = STATUS_WAIT_S,
    pattern: str = "*",
    creds: Credentials | None = None,
) -> list[RobotRecord]:
    """:func:`discover` through a session of its own to ``endpoint`` (a router, or a robot),
    logged in as ``creds`` (None: the environment's or the client file's)."""
    session = connect(
        endpoint,
        f"nothing answers at {endpoint}",
        "is `darwin router` (or `darwin up`) running there? Pass the address it printed with "
        "--connect",
        creds=creds,
    )
    try:
        return discover(session, timeout, pattern)
    finally:
        with contextlib.suppress(Exception):
            session.close()
