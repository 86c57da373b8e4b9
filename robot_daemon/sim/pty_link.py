"""The emulator's end of the serial line: a pseudo-terminal, optionally behind a stable symlink.

The emulator reads and writes the master side; clients open the slave path with pyserial as
they would ``/dev/ttyUSB0``. The emulator keeps its own slave descriptor open, because reads on
the master fail with EIO while no process has the slave open. The slave is put in raw mode here
(no echo, no line discipline); any baud rate a client sets is accepted and ignored.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import tty
from pathlib import Path


class PtyLink:
    def __init__(self, link: str | os.PathLike[str] | None = None) -> None:
        self.link = Path(link) if link else None
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
