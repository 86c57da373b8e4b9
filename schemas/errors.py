"""The project's one exception tree. Every layer raises these, translated once at its boundary.

DarwinError
├── ConfigError             a config file or value is wrong
├── BusError                serial port and Dynamixel bus
│   ├── PortError           cannot open / lost the serial port
│   │   └── PortInUseError  another process holds it
│   ├── NoReplyError        a device did not answer
│   └── PacketError         a reply was corrupt or malformed
├── ProtocolError           malformed input on a wire (legacy framing, JSON)
├── CommandError            the arbiter refused a command (code, field)
│   ├── LeaseBusyError      another client holds the control lease
│   ├── NoLeaseError        the command needs the lease and the caller has none
│   └── InvalidCommandError a field is missing, of the wrong type or out of range
└── ClientError             client side: cannot reach the robot, timed out
    ├── RobotUnreachableError
    └── CommandTimeoutError
"""

from __future__ import annotations

from enum import StrEnum


class ErrorCode(StrEnum):
    """Codes carried by arbiter error replies (and legacy gateway error messages)."""

    BUSY = "busy"  # lease held by another client
    NO_LEASE = "no_lease"  # command needs the lease
    INVALID = "invalid"  # malformed field, wrong type
    OUT_OF_RANGE = "out_of_range"  # value outside configured limits
    UNKNOWN = "unknown"  # unknown joint, page, behaviour, verb
    UNAVAILABLE = "unavailable"  # joint offline, module not running, feature off
    REFUSED = "refused"  # not allowed in this state (e.g. EEPROM write without flag)
    INTERNAL = "internal"  # a bug: the daemon says so instead of crashing


class DarwinError(Exception):
    """Base of every error this project raises on purpose."""


class ConfigError(DarwinError):
    pass


class BusError(DarwinError):
    pass


class PortError(BusError):
    pass


class PortInUseError(PortError):
    pass


class NoReplyError(BusError):
    pass


class PacketError(BusError):
    pass


class ProtocolError(DarwinError):
    pass


class CommandError(DarwinError):
    """An arbiter error reply, raised on the client side."""

    def __init__(self, code: str, message: str, field: str | None = None, verb: str = ""):
        self.code = code
        self.message = message
        self.field = field
        self.verb = verb
        where = f" (field {field!r})" if field else ""
        prefix = f"{verb}: " if verb else ""
        super().__init__(f"{prefix}{code}: {message}{where}")


class LeaseBusyError(CommandError):
    pass


class NoLeaseError(CommandError):
    pass


class InvalidCommandError(CommandError):
    pass


class ClientError(DarwinError):
    pass


class RobotUnreachableError(ClientError):
    pass


class CommandTimeoutError(ClientError):
    pass


_BY_CODE: dict[str, type[CommandError]] = {
    ErrorCode.BUSY: LeaseBusyError,
    ErrorCode.NO_LEASE: NoLeaseError,
    ErrorCode.INVALID: InvalidCommandError,
    ErrorCode.OUT_OF_RANGE: InvalidCommandError,
    ErrorCode.UNKNOWN: InvalidCommandError,
}


def command_error(
    code: str, message: str, field: str | None = None, verb: str = ""
) -> CommandError:
    """The exception class that matches an error reply's code."""
    return _BY_CODE.get(code, CommandError)(code, message, field, verb)
