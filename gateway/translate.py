"""Legacy requests to arbiter commands (verb + fields in the verb's SI units). Pure: no I/O.

Whether a command needs the control lease is read from the contract (``schemas``), never
decided here, so the gateway asks for the lease exactly when the arbiter would want it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gateway.messages import JOINT_IDS, Led, Operate, Playball, Request, Walk
from gateway.settings import GatewaySettings, WalkMapping
from schemas import units
from schemas.commands import needs_lease


@dataclass(frozen=True)
class Command:
    """A daemon verb and its fields: what a legacy request becomes."""

    verb: str
    fields: dict[str, Any]

    @property
    def needs_lease(self) -> bool:
        return needs_lease(self.verb, self.fields)


def deg_to_rad(deg: float) -> float:
    """Degrees to rad at the servo's own resolution (the conversion the bus applies)."""
    return units.raw_to_rad(units.deg_to_raw(deg))


def operate_command(req: Operate, all_duration: float) -> Command:
    rad = deg_to_rad(req.position_deg)
    if req.joint is None:
        positions = {str(jid): rad for jid in JOINT_IDS}
        return Command("pose", {"positions": positions, "duration": all_duration})
    return Command("joint", {"id": req.joint, "position": rad})


def led_command(req: Led) -> Command:
    return Command("led", {req.target: list(req.rgb)})


def walk_command(req: Walk, mapping: WalkMapping) -> Command:
    """Start walking, or change the speeds of a walk already running (``start`` does both)."""
    if req.stop:
        return Command("walk", {"op": "stop"})
    return Command(
        "walk",
        {
            "op": "start",
            "x": req.x * mapping.x_mps_per_unit,
            "y": req.y * mapping.y_mps_per_unit,
            "turn": req.a * mapping.a_radps_per_unit,
        },
    )


def playball_command(req: Playball) -> Command:
    return Command("playball", {"op": "start" if req.start else "stop"})


def orchestrate_stop_command() -> Command:
    return Command("choreography", {"op": "stop"})


def request_command(req: Request, settings: GatewaySettings) -> Command | None:
    """The one arbiter command a request stands for; None for monitor (served by the gateway)
    and orchestrate (the orchestrator's, which needs the daemon's behaviour table)."""
    if isinstance(req, Operate):
        return operate_command(req, settings.operate_all_duration)
    if isinstance(req, Led):
        return led_command(req)
    if isinstance(req, Walk):
        return walk_command(req, settings.walk)
    if isinstance(req, Playball):
        return playball_command(req)
    return None
