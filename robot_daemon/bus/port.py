"""The serial port: opened exclusively, read with a blocking, time-bounded wait.

The SDK's receive loop calls ``readPort`` until the bytes are there or its packet timeout
passes; with pyserial's ``timeout=0`` that loop spins a CPU core. Here ``readPort`` waits in
``select`` for the bytes or the deadline, so waiting on the bus costs no CPU.

Exclusive access has two layers: a lock file holding the owner's PID (so a second process gets
"in use by PID …" instead of a garbled bus) and ``TIOCEXCL`` on the tty itself.
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import os
import select
import termios
from pathlib import Path

import serial

from robot_daemon.bus.preflight import (
    LISTEN_S,
    check_holders,
    check_latency,
    latency_timer_ms,
    refuse_unasked,
)
from robot_daemon.bus.transport import Transport
from schemas.errors import PortError, PortInUseError

log = logging.getLogger(__name__)

# What pyserial raises when the device goes away under it: OS errors, its own exception,
# termios errors from tcflush, and TypeError/AttributeError/ValueError once its fd is gone.
_PORT_FAILURES = (
    OSError,
    serial.SerialException,
    termios.error,
    TypeError,
    AttributeError,
    ValueError,
)

LOCK_DIR = Path(os.environ.get("DARWIN_LOCK_DIR", "/tmp"))


def lock_path(port_name: str) -> Path:
    real = os.path.realpath(port_name)
    return LOCK_DIR / f"darwin-{real.strip('/').replace('/', '_')}.lock"


class PortLock:
    """An flock'd lock file naming the PID that owns a serial port."""

    def __init__(self, port_name: str) -> None:
        self.port_name = port_name
        self.path = lock_path(port_name)
        self._fd: int | None = None

    def acquire(self) -> None:
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            owner = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            raise PortInUseError(
                f"serial port {self.port_name} is in use by PID {owner} (lock {self.path}); "
                "stop that process (another `darwin daemon`?) or choose another --port"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self._fd = fd

    def release(self) -> None:
        if self._fd is not None:
            with contextlib.suppress(OSError):
                os.ftruncate(self._fd, 0)
            os.close(self._fd)
            self._fd = None


class BlockingPortHandler(Transport):
    """The serial transport: a dynamixel-sdk ``PortHandler`` that never spins and owns its port
    exclusively. How long a reply is waited for is the bus layer's to say (``dxl.ReplyBudget``
    sets the packet timeout for every wait)."""

    def __init__(self, port_name: str) -> None:
        super().__init__(port_name)
        self._lock = PortLock(port_name)

    # -- open / close ----------------------------------------------------------------------
    def open(self, baudrate: int) -> None:
        """Open the port exclusively or raise ``PortError``/``PortInUseError``."""
        if not os.path.exists(self.port_name):
            raise PortError(
                f"serial port {self.port_name} does not exist; is the robot's USB cable in "
                "(`ls /dev/ttyUSB*`), or is the emulator running (`darwin sim`)?"
            )
        self._lock.acquire()
        try:
            check_holders(self.port_name)  # a plain open() (ROBOTIS's demo) takes no lock
            self.baudrate = baudrate
            if not self.setBaudRate(baudrate):
                raise PortError(f"baud rate {baudrate} is not supported on {self.port_name}")
            check_latency(self.port_name)  # after asking for low latency in setupPort
            # Listen before talking: another master's replies arrive unasked.
            refuse_unasked(self.port_name, self.unasked_bytes(LISTEN_S))
        except serial.SerialException as exc:
            self._lock.release()
            if "lock" in str(exc).lower():
                raise PortInUseError(
                    f"serial port {self.port_name} is locked by another process: {exc}"
                ) from exc
            raise PortError(f"cannot open serial port {self.port_name}: {exc}") from exc
        except BaseException:
            self.close()
            raise

    def setupPort(self, cflag_baud: int) -> bool:
        if self.is_open:
            self.closePort()
        self.ser = serial.Serial(
            port=self.port_name,
            baudrate=self.baudrate,
            bytesize=serial.EIGHTBITS,
            timeout=0,
            exclusive=True,
        )
        with contextlib.suppress(OSError):
            # Refuse any further open() of the tty (root still may: the lock file covers that).
            fcntl.ioctl(self.ser.fileno(), termios.TIOCEXCL)
        with contextlib.suppress(Exception):
            # ftdi_sio sets its latency timer to 1 ms for ASYNC_LOW_LATENCY (a pty refuses).
            self.ser.set_low_latency_mode(True)
        self.is_open = True
        self.ser.reset_input_buffer()
        self.set_baud(self.baudrate)
        return True

    def close(self) -> None:
        if self.ser is not None:
            with contextlib.suppress(Exception):
                fcntl.ioctl(self.ser.fileno(), termios.TIOCNXCL)
            with contextlib.suppress(Exception):
                self.ser.close()
        self.is_open = False
        self._lock.release()

    # -- the SDK's I/O hooks ---------------------------------------------------------------
    def readPort(self, length: int) -> bytes:
        try:
            data: bytes = self.ser.read(length)
            if data:
                self.bytes_read += len(data)
                return data
            remaining = (self.packet_timeout - self.getTimeSinceStart()) / 1000.0
            if remaining <= 0:
                return b""
            ready, _, _ = select.select([self.ser.fileno()], [], [], remaining)
            if not ready:
                return b""
            data = self.ser.read(length)
        except _PORT_FAILURES as exc:
            raise PortError(f"serial port {self.port_name} failed while reading: {exc}") from exc
        if not data:
            # select said readable but nothing came: the device is gone (EOF / hang-up).
            raise PortError(f"serial port {self.port_name} vanished (read returned EOF)")
        self.bytes_read += len(data)
        return data

    def read_chunk(self, deadline_ms: float) -> bytes:
        # os.read on pyserial's non-blocking descriptor: pyserial's read() costs a select and
        # its bookkeeping on every call, and this runs once per arriving chunk.
        try:
            fd = self.ser.fd
            try:
                data = os.read(fd, 4096)
            except BlockingIOError:
                data = b""
            if data:
                self.bytes_read += len(data)
                return data
            remaining = (deadline_ms - self.getCurrentTime()) / 1000.0
            if remaining <= 0:
                return b""
            ready, _, _ = select.select([fd], [], [], remaining)
            if not ready:
                return b""
            data = os.read(fd, 4096)
        except BlockingIOError:
            return b""
        except _PORT_FAILURES as exc:
            raise PortError(f"serial port {self.port_name} failed while reading: {exc}") from exc
        if not data:
            raise PortError(f"serial port {self.port_name} vanished (read returned EOF)")
        self.bytes_read += len(data)
        return data

    def unasked_bytes(self, seconds: float) -> int:
        """How many bytes arrive in ``seconds`` while nothing is sent."""
        deadline = self.getCurrentTime() + seconds * 1000.0
        count = 0
        while chunk := self.read_chunk(deadline):
            count += len(chunk)
        return count

    def writePort(self, packet: list[int] | bytes) -> int:
        # os.write on the descriptor: pyserial's write() adds a select and a loop per call,
        # twice a tick. The descriptor is non-blocking; a full output buffer is waited out.
        data = memoryview(bytes(packet))
        fd = self.ser.fd if self.ser is not None else None
        try:
            if fd is None:
                raise OSError("the port is closed")
            sent = 0
            while sent < len(data):
                try:
                    sent += os.write(fd, data[sent:])
                except BlockingIOError:
                    if not select.select([], [fd], [], 0.1)[1]:
                        break  # the line is stuck: the caller reports a short write
        except _PORT_FAILURES as exc:
            raise PortError(f"serial port {self.port_name} failed while writing: {exc}") from exc
        self.bytes_written += sent
        return sent

    def clearPort(self) -> None:
        # Read and drop what is waiting (a late reply to an earlier transaction) rather than
        # tcflush: the same bytes go, at a fraction of the cost on every instruction sent.
        fd = self.ser.fd if self.ser is not None else None
        try:
            if fd is None:
                raise OSError("the port is closed")
            while True:
                try:
                    if not os.read(fd, 4096):
                        return  # nothing waiting (VMIN = VTIME = 0: an empty read)
                except BlockingIOError:
                    return
        except _PORT_FAILURES as exc:
            raise PortError(f"serial port {self.port_name} failed: {exc}") from exc

    def latency_timer_ms(self) -> int | None:
        return latency_timer_ms(self.port_name)
