"""The hardware emulator: a CM-730 and 20 MX-28 servos answering Dynamixel 1.0 on a pty.

``Emulator`` (in-process, ``with Emulator(...) as emu: emu.port``); ``darwin sim`` runs the same
in a process of its own (:mod:`robot_daemon.plant.sim_cli`, with the world). Byte-faithful: the
register tables (``devices``, ``control_table``), the servo chain answering packets
(``servo_chain``, ``wiring``, ``bringup``), the pty and FTDI delivery (``pty_link``, ``ftdi``),
faults, the clock, and the in-process link (``inprocess_link``). What stands behind the servos
plugs in through the seam in ``api`` and ``clock`` (physics hooks, present positions, body
motion) and the control ops (``op_table``); the plant (:mod:`robot_daemon.plant`) imports this
package, never the other way round.
"""

from robot_daemon.emulator.emulator import Emulator
from robot_daemon.emulator.settings import EmulatorSettings

__all__ = ["Emulator", "EmulatorSettings"]
