"""The project's one exception tree. Every layer raises these, translated once at its boundary.

DarwinError
├── ConfigError             a config file or value is wrong
├── StateError              an object used in the wrong state (closed, already running)
├── CameraError             a camera source gives no frames or cannot encode them
│   ├── GLUnavailableError  no OpenGL for the MuJoCo camera (robot_daemon/plant/physics)
│   └── V4L2Error           a V4L2 camera that cannot be opened or give MJPEG (vision/v4l2)
├── ChildError              a program `darwin up` started exited or never became ready
├── ListenError             the daemon can't listen on Zenoh (robot_daemon/engine/zenoh_setup)
├── RouterError             `darwin router` cannot listen (robot_daemon/launch/router)
├── MotionFileError         a motion file that cannot be read (robot_daemon/motion/action)
├── ReplaceRefused          a servo replacement that would be unsafe (robot_daemon/bus/replace)
├── ServiceError            the boot service cannot be installed, removed or read here
├── JoinError               a robot cannot join its router, or the router cannot see it
├── PolicyLoadError         a policy file that cannot be loaded (clients/learn/onnx_policy)
├── MissingExtraError       an optional package is not installed; names the extra (schemas/extras)
├── BusError                serial port and Dynamixel bus
│   ├── PortError           cannot open / lost the serial port
│   │   ├── PortInUseError  another process holds it
│   │   └── SlowPortError   the USB latency timer is above 1 ms
│   ├── NoReplyError        a device did not answer
│   └── PacketError         a reply was corrupt or malformed
├── ProtocolError           malformed input on a wire (legacy framing, JSON, msgpack)
│   ├── PayloadTooLargeError a payload over the size limit, refused before decoding
│   ├── SlowReaderError     a peer lets replies pile up: closed rather than buffered
│   ├── LegacyError         the legacy protocol's errors (gateway/messages.py)
│   │   ├── FramingError    the byte stream cannot be framed: closed after the error reply
│   │   └── MessageError    a well-framed message that cannot be applied: answered, kept
│   ├── AdapterInputError   a request an adapter (ROS 2, Foxglove) refuses before the arbiter
│   ├── CdrError            a ROS 2 message whose CDR bytes do not decode (clients/ros2)
│   └── AttachmentError     an rmw_zenoh attachment that does not decode (clients/ros2)
├── RecordingError          a recording cannot be read or recovered (clients/recording)
│   ├── NotMcapError        the file holds no MCAP data at all
│   └── RecoverError        nothing could be recovered, or the output is not allowed
├── EditError               a page edit that cannot be made (clients/pages.py)
├── CommandError            a refused command (code, message, field); one class per ErrorCode
│   ├── LeaseBusyError      busy: another client holds the control lease
│   ├── NoLeaseError        no_lease: the command needs the lease and the caller has none
│   ├── InvalidCommandError invalid: a field is missing, unknown or of the wrong type
│   │   ├── FieldError      the same, raised by a handler for one named field
│   │   ├── BehaviourError  a behaviour or choreography item that cannot be played
│   │   ├── OutOfRangeError out_of_range: a value outside its limits (or a payload too long)
│   │   └── UnknownNameError unknown: no such joint, page, behaviour, op
│   ├── UnavailableError    unavailable: offline joint, lost port, feature off
│   ├── RefusedError        refused: not allowed here (EEPROM/hardware write without the switch)
│   ├── RateLimitedError    rate_limited: too many commands; retry after ``retry_after`` s
│   ├── ForbiddenError      forbidden: the caller's role may not do this; ``role`` names the one
│   │                       that may (``schemas.roles``)
│   ├── InternalError       internal: a daemon bug, reported instead of crashing
│   └── Reject              the daemon side's refusal inside a handler (any code)
└── ClientError             client side: cannot reach the robot, timed out
    ├── RobotUnreachableError
    ├── CommandTimeoutError
    └── IncompatibleProtocolError the daemon speaks a protocol major this client does not

Error replies carry the code; :func:`command_error` turns a code back into its class, and
``cls.CODE`` gives the code of a class, so both sides agree by construction.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Any, ClassVar


class ErrorCode(StrEnum):
    """Codes carried by arbiter error replies (and legacy gateway error messages)."""

    BUSY = "busy"  # lease held by another client
    NO_LEASE = "no_lease"  # command needs the lease
    INVALID = "invalid"  # malformed field, unknown field, wrong type
    OUT_OF_RANGE = "out_of_range"  # value outside configured limits, string/list/payload too long
    UNKNOWN = "unknown"  # unknown joint, page, behaviour, verb
    UNAVAILABLE = "unavailable"  # joint offline, module not running, feature off
    REFUSED = "refused"  # not allowed in this state (e.g. EEPROM write without flag)
    # Too many commands (per client, or the loop's queue is full): nothing was applied; the
    # reply's ``retry_after`` (s) says when to try again. Distinct from ``busy``, which is about
    # the lease, so a client never mistakes a throttled command for a lost lease.
    RATE_LIMITED = "rate_limited"
    INTERNAL = "internal"  # a bug: the daemon says so instead of crashing
    # The caller's role may not do this (``schemas.roles``); the message names the role that
    # may. Raised by the client before sending, or by the arbiter for an admin-only op on cmd/.
    FORBIDDEN = "forbidden"


def brief(value: Any, limit: int = 40) -> str:
    """``repr(value)`` cut to ``limit`` characters: error messages echo a bad value, never all
    of a large one."""
    if isinstance(value, str | bytes | bytearray) and len(value) > 4 * limit:
        value = value[: 2 * limit]  # never repr a megabyte to throw it away
    text = repr(value)
    return text if len(text) <= limit else f"{text[: limit - 1]}… ({type(value).__name__})"


class DarwinError(Exception):
    """Base of every error this project raises on purpose."""


class ConfigError(DarwinError):
    """A config file or value is wrong (unreadable TOML, a missing key, a limit out of order, a
    bad ``--listen`` endpoint); the message names the file or option to fix."""


class StateError(DarwinError):
    """An object used in the wrong state: a closed or already-used one (a ``Replayer`` run
    twice)."""


class CameraError(DarwinError):
    """A camera source gives no frames or cannot encode them (no such device or model camera, a
    closed source, an encoder failure)."""


class BusError(DarwinError):
    """The serial port or the Dynamixel bus failed a transfer; the subclasses say which part."""


class PortError(BusError):
    """The serial port cannot be opened (missing, unsupported baud rate) or was lost."""


class PortInUseError(PortError):
    """Another process holds the serial port (its lock file or the serial driver's lock); the
    message names the holder's PID where the lock file has it."""


class SlowPortError(PortError):
    """The serial adapter would make every reply late (an FTDI latency timer above 1 ms): the
    daemon refuses to drive the robot until it is set to 1."""


class NoReplyError(BusError):
    """A device on the bus did not answer in time: offline, unpowered or a wrong ID."""


class PacketError(BusError):
    """A reply came back corrupt or malformed (checksum, length, header)."""


class ProtocolError(DarwinError):
    """Malformed input on a wire: legacy framing, JSON, msgpack or a payload of the wrong shape
    or schema version."""


class AdapterInputError(ProtocolError, ValueError):
    """A request an adapter (ROS 2, Foxglove) refuses before it reaches the arbiter: not JSON,
    a field of the wrong type, a speed that is not finite, a joint the robot does not have."""


class RecordingError(DarwinError):
    """A recording cannot be read or recovered; the message names the file and what is wrong."""


class PayloadTooLargeError(ProtocolError):
    """A payload over the size limit, refused before it is decoded."""


class SlowReaderError(ProtocolError):
    """A client let too many replies pile up: it is closed rather than buffered forever."""


class CommandError(DarwinError):
    """A refused command: an arbiter (or control queryable) error reply, raised on the client
    side; on the daemon side :class:`Reject`."""

    CODE: ClassVar[str] = ""  # the ErrorCode of this class ("" for the base and Reject)

    def __init__(
        self,
        code: str,
        message: str,
        field: str | None = None,
        verb: str = "",
        retry_after: float | None = None,
    ):
        self.code = str(code)
        self.message = message
        self.field = field
        self.verb = verb
        self.retry_after = retry_after
        where = f" (field {field!r})" if field else ""
        prefix = f"{verb}: " if verb else ""
        super().__init__(f"{prefix}{self.code}: {message}{where}")


class LeaseBusyError(CommandError):
    """``busy``: another client holds the control lease; wait for it to release or expire."""

    CODE = ErrorCode.BUSY


class NoLeaseError(CommandError):
    """``no_lease``: the command needs the control lease and the caller does not hold it."""

    CODE = ErrorCode.NO_LEASE


class InvalidCommandError(CommandError):
    """``invalid``: a field is missing, unknown or of the wrong type; ``field`` names it."""

    CODE = ErrorCode.INVALID


class FieldError(InvalidCommandError, ValueError):
    """A handler's refusal of one named field (``FieldError("x", "x must be …")``)."""

    def __init__(self, field_name: str, message: str) -> None:
        super().__init__(ErrorCode.INVALID, message, field_name)


class BehaviourError(InvalidCommandError, ValueError):
    """A behaviour or item that cannot be played; ``field`` names the offending field."""

    def __init__(self, message: str, field: str | None = None) -> None:
        super().__init__(ErrorCode.INVALID, message, field)

    def __str__(self) -> str:
        return self.message


class OutOfRangeError(InvalidCommandError):
    """``out_of_range``: a value outside its configured limits, or a string, list or payload
    longer than allowed."""

    CODE = ErrorCode.OUT_OF_RANGE


class UnknownNameError(InvalidCommandError):
    """``unknown``: no such joint, page, behaviour, verb or op."""

    CODE = ErrorCode.UNKNOWN


class UnavailableError(CommandError):
    """``unavailable``: the target cannot act now (a joint offline, the port lost, a module not
    running or a feature turned off)."""

    CODE = ErrorCode.UNAVAILABLE


class RefusedError(CommandError):
    """``refused``: not allowed in this state, such as an EEPROM or hardware write without the
    switch that enables it."""

    CODE = ErrorCode.REFUSED


class RateLimitedError(CommandError):
    """``rate_limited``: too many commands; nothing was applied, retry after ``retry_after`` s."""

    CODE = ErrorCode.RATE_LIMITED


class InternalError(CommandError):
    """``internal``: a bug in the daemon (or a server), reported instead of crashing it."""

    CODE = ErrorCode.INTERNAL


class ForbiddenError(CommandError):
    """The caller's role may not send this; ``role`` is the least role that may."""

    CODE = ErrorCode.FORBIDDEN
    # Set where it is known (``schemas.roles.check``, before sending); "" when not said.
    role: str = ""


class Reject(CommandError):
    """Refuse a command on the daemon side: becomes an error reply ``{code, message, field}``."""

    def __init__(
        self,
        code: ErrorCode | str,
        message: str,
        field: str | None = None,
        retry_after: float | None = None,
    ) -> None:
        super().__init__(str(code), message, field, retry_after=retry_after)

    def __str__(self) -> str:
        return self.message


class ClientError(DarwinError):
    """Client side: the client cannot do what was asked (a closed ``Robot`` or ``Recorder``, a
    recording in the way, a page step that does not exist); the message says what to do."""


class RobotUnreachableError(ClientError):
    """No daemon answers at the endpoint, or the Zenoh session failed."""


class CommandTimeoutError(ClientError):
    """The daemon did not reply to a command in time, or a wait for a message or camera frame
    ran out."""


# One class per code; the reverse is ``cls.CODE``.
ERROR_CLASSES: dict[str, type[CommandError]] = {
    cls.CODE: cls
    for cls in (
        LeaseBusyError,
        NoLeaseError,
        InvalidCommandError,
        OutOfRangeError,
        UnknownNameError,
        UnavailableError,
        RefusedError,
        RateLimitedError,
        InternalError,
        ForbiddenError,
    )
}


def command_error(
    code: str,
    message: str,
    field: str | None = None,
    verb: str = "",
    retry_after: float | None = None,
) -> CommandError:
    """The exception that matches an error reply's code (``CommandError`` for a code this build
    does not know, e.g. from a newer daemon)."""
    return ERROR_CLASSES.get(str(code), CommandError)(code, message, field, verb, retry_after)


class IncompatibleProtocolError(ClientError):
    """The daemon speaks a protocol major this client does not (``schemas/versions.py``)."""
