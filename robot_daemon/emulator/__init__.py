"""The hardware emulator: a CM-730 and 20 MX-28 servos answering Dynamixel 1.0 on a pty.

``Emulator`` (in-process, ``with Emulator(...) as emu: emu.port``); ``darwin sim`` runs the same
in a process of its own (:mod:`robot_daemon.plant.sim_cli`, with the world). Byte-faithful: the
register tables (``devices``, ``control_table``), the servo chain answering packets
(``servo_chain``, ``wiring``, ``bringup``), the pty and FTDI delivery (``pty_link``, ``ftdi``),
faults, the clock, and the in-process link (``inprocess_link``). What stands behind the servos
plugs in through the seam in ``api`` and ``clock`` (physics hooks, present positions, body
motion) and the control ops (``op_table``); the plant (:mod:`robot_daemon.plant`) imports this
package, never the other way round.

The names below are imported when first used: a program that only forwards options to the
emulator (``darwin up``, ``darwin daemon --sim`` read :mod:`.options`) does not pay for the
emulator itself (numpy and the servo chain) or its settings at start-up.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from robot_daemon.emulator.emulator import Emulator
    from robot_daemon.emulator.settings import EmulatorSettings

__all__ = ["Emulator", "EmulatorSettings"]
_WHERE = {
    "Emulator": "robot_daemon.emulator.emulator",
    "EmulatorSettings": "robot_daemon.emulator.settings",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
