"""What the wire decides in the emulator: which devices hear the host (baud rate, cable breaks)
and what a servo straight out of its box looks like.

* A device hears the host only when its baud rate register's rate is within a UART's tolerance
  of the line's rate (2 Mbps / (register + 1), Protocol 1.0); at any other rate the bytes it
  sees are noise and it stays silent. So a factory-fresh MX-28 (57,600 bps) answers only when
  the host's port is at 57,600, and the robot's servos (1 Mbps) only at 1 Mbps. The rate is
  read when the bytes reach the emulator, so a host that changes rate must first let its last
  instruction go (wait for its reply or time-out), as a real UART needs its bytes drained.
* A broken chain (``broken_after``): every servo behind the break on its branch
  (:mod:`robot_daemon.bus.chains`) neither hears nor answers, nor gets power.
* A factory-fresh MX-28 (ROBOTIS e-manual, MX-28 control table, factory defaults): ID 1,
  baud register 34 (57,600 bps), return delay 250 (500 µs), angle limits 0..4095, every other
  EEPROM value at its default.
"""

from __future__ import annotations

from robot_daemon.bus.tables import MX28
from robot_daemon.emulator.devices import Device, Servo
from schemas import units

# A UART still frames bytes whose rate is this close to its own (the MX-28's 57,142 bps for
# "57,600" is 0.8 % off; 3 % is the usual limit of an 8N1 receiver).
BAUD_TOLERANCE = 0.03
FRESH_ID = 1
FRESH_BAUD_REGISTER = 34
FRESH_RETURN_DELAY = 250


def hears(device: Device, line_bps: int) -> bool:
    rate = units.baud_register_to_bps(device.table[device.regs.BAUD_RATE])
    return abs(rate - line_bps) <= BAUD_TOLERANCE * line_bps


def make_factory_fresh(servo: Servo) -> None:
    """Every EEPROM value of ``servo`` as it leaves the factory (RAM as at power-on)."""
    servo.table.reset()
    servo.table[MX28.ID] = FRESH_ID
    servo.table[MX28.BAUD_RATE] = FRESH_BAUD_REGISTER
    servo.table[MX28.RETURN_DELAY_TIME] = FRESH_RETURN_DELAY
    if servo.powered:
        servo.table[MX28.GOAL_POSITION] = round(servo.position)
