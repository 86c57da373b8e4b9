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
    STOPPING = "stopping"
