"""The servos' power, watched every tick in the CM-730's sensor block.

The CM-730 switches the Dynamixel bus's power (DXL_POWER, address 24, the first byte of its
bulk-read block). Its reset button or a supply glitch turns it off: the servos go silent and
limp, and nothing else on the bus says why (the bulk read just loses them). On a valid CM-730
reading of 0 the daemon halts, reports it, and re-runs power-on, scan and hold
(``Daemon._port_lost`` / ``_reconnect``), as ROBOTIS's framework does only at start
(``CM730::Connect`` → ``DXLPowerOn``, ``Framework/src/CM730.cpp``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from schemas.errors import DxlPowerLostError

if TYPE_CHECKING:
    from robot_daemon.bus.robot_bus import RobotBus


def check_dxl_power(bus: RobotBus) -> None:
    """Raise ``DxlPowerLostError`` when this tick's valid CM-730 block says DXL power is off."""
    if bus.cm730_valid and bus.cm730[0] == 0:
        raise DxlPowerLostError(
            f"DXL power went off (the CM-730 on {bus.port_name} reads DXL_POWER 0: its reset "
            "button, or a supply glitch): the servos are limp; powering them again, then scan "
            "and hold"
        )
