"""The daemon's state, as ``status.state`` carries it.

Here rather than in the daemon so a client can name a state without importing the daemon: a
``StrEnum`` compares equal to its string, so ``status.state == DaemonState.RUNNING`` holds for
the plain string a decoded ``Status`` has.
"""

from __future__ import annotations

from enum import StrEnum


class DaemonState(StrEnum):
    STARTING = "starting"
    SCANNING = "scanning"
    RUNNING = "running"
    DEGRADED = "degraded"
    PORT_LOST = "port_lost"
    # DXL power went off (the CM-730's reset button): every servo limp until powered again.
    SERVOS_OFF = "servos_off"
    STOPPING = "stopping"
