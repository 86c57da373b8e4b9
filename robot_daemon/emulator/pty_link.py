"""The emulator's end of the serial line: a pseudo-terminal, optionally behind a stable symlink.

The emulator reads and writes the master side; clients open the slave path with pyserial as
they would ``/dev/ttyUSB0``. The emulator keeps its own slave descriptor open, because reads on
the master fail with EIO while no process has the slave open. The slave is put in raw mode here
(no echo, no line discipline) at ``baud``; the baud rate a client sets on the slave is what
:meth:`PtyLink.baud` reads back (a pty's two ends share one termios), so the emulator can let
only the devices at that rate hear it, as on a real wire.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import termios
import tty
from pathlib import Path


class PtyLink:
    def __init__(self, link: str | os.PathLike[str] | None = None, baud: int = 1_000_000) -> None:
        self.link = Path(link) if link else None
        self.initial_baud = baud
        self.master: int | None = None
        self._slave: int | None = None
        self.slave_path = ""

    @property
    def is_open(self) -> bool:
        return self.master is not None

    @property
    def path(self) -> str:
        """What clients open: the symlink if there is one, else the slave device."""
        return str(self.link) if self.link else self.slave_path

    def open(self) -> None:
        if self.master is not None:
            return
        master, slave = os.openpty()
        tty.setraw(slave)
        _set_speed(slave, self.initial_baud)
        flags = fcntl.fcntl(master, fcntl.F_GETFL)
        fcntl.fcntl(master, fcntl.F_SETFL, flags | os.O_NONBLOCK)
        self.master, self._slave = master, slave
        self.slave_path = os.ttyname(slave)
        if self.link:
            self._relink()

    def _relink(self) -> None:
        assert self.link is not None
        if self.link.exists() and not self.link.is_symlink():
            raise FileExistsError(
                f"{self.link} exists and is not a symlink; choose another --link path"
            )
        tmp = self.link.with_name(f".{self.link.name}.{os.getpid()}.tmp")
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        os.symlink(self.slave_path, tmp)
        os.replace(tmp, self.link)  # atomic: a client never sees the link missing while we relink

    def close(self) -> None:
        """Close both ends and remove the link: clients see the port vanish."""
        for fd in (self.master, self._slave):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self.master = self._slave = None
        if self.link and self.link.is_symlink():
            with contextlib.suppress(FileNotFoundError):
                self.link.unlink()

    def baud(self) -> int | None:
        """The line's baud rate as the client last set it (None: closed or not a standard rate)."""
        if self.master is None:
            return None
        try:
            speed = termios.tcgetattr(self.master)[5]
        except termios.error:
            return None
        return _SPEEDS.get(speed)

    def read(self, n: int = 4096) -> bytes:
        assert self.master is not None
        try:
            return os.read(self.master, n)
        except BlockingIOError:
            return b""
        except OSError as exc:
            if exc.errno == errno.EIO:  # no slave open; cannot happen while we hold ours
                return b""
            raise

    def write(self, data: bytes) -> int:
        """Write what the line accepts; bytes a full input queue refuses are lost, as on a wire."""
        assert self.master is not None
        try:
            return os.write(self.master, data)
        except BlockingIOError:
            return 0


# termios speed constants → bits per second (the rates pyserial sets with a plain tcsetattr).
_SPEEDS: dict[int, int] = {
    getattr(termios, f"B{bps}"): bps
    for bps in (
        9600,
        19200,
        38400,
        57600,
        115200,
        230400,
        460800,
        500000,
        576000,
        921600,
        1000000,
        1152000,
        1500000,
        2000000,
        2500000,
        3000000,
        3500000,
        4000000,
    )
    if hasattr(termios, f"B{bps}")
}


def _set_speed(fd: int, bps: int) -> None:
    """Start the line at ``bps`` so a client that never sets a rate is heard at the
    emulator's configured one."""
    code = next((c for c, b in _SPEEDS.items() if b == bps), None)
    if code is None:
        return
    attrs = termios.tcgetattr(fd)
    attrs[4] = attrs[5] = code
    termios.tcsetattr(fd, termios.TCSANOW, attrs)
