"""The hardware emulator: a CM-730 and 20 MX-28 servos answering Dynamixel 1.0 on a pty.

``Emulator`` (in-process, ``with Emulator(...) as emu: emu.port``) and ``darwin sim`` (the same
in a process of its own). The simulated world lives in ``robot_daemon.sim.world``.
"""

from robot_daemon.sim.emulator import Emulator
from robot_daemon.sim.settings import EmulatorSettings

__all__ = ["Emulator", "EmulatorSettings"]
