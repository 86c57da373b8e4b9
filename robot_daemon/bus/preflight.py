"""What must be true before the daemon drives a real robot's bus, checked when the port opens.

* **Nobody else holds the tty.** The stock DARwIn-OP image starts ROBOTIS's demo from
  ``/etc/rc.local``; it opens the port with a plain ``open()`` (``Linux/build/LinuxCM730.cpp``,
  ``LinuxCM730::OpenPort``), which neither our lock file nor ``TIOCEXCL`` stops once it has the
  port: two masters on one bus garble every transaction. So ``/proc/*/fd`` is searched for the
  device, and the daemon refuses to start while another process has it, naming it. A process
  that also holds the pty's master (``/dev/ptmx`` with the same ``tty-index``) is the emulator,
  the device's end of the wire, not a second master.
  A daemon that is not root cannot read a root process's ``/proc/PID/fd`` (ROBOTIS's demo runs
  as root from ``/etc/rc.local``), so that check alone misses the demo:
* **Nobody else talks on the line.** Before its first byte the daemon listens for
  ``LISTEN_S``: bytes arriving unasked are another master's traffic (the demo bulk-reads every
  8 ms), and it refuses in one line naming ``/etc/rc.local`` and the demo.
* **Nobody opens the port later.** While the daemon runs, a thread looks at the port's holders
  (:class:`HolderWatch`) when the kernel says someone opened or closed it (inotify), or every
  ``daemon.holder_check_s`` where it cannot; a new one halts the motion and is reported (two
  masters sync-writing every 8 ms make the servos chatter and fight).
* **The FTDI latency timer is 1 ms.** The FTDI chip holds received bytes until 62 have come or
  the timer runs out (16 ms by default on current kernels), so with 16 ms the CM-730's reply
  arrives late every tick. ``set_low_latency_mode(True)`` (``TIOCSSERIAL`` with
  ``ASYNC_LOW_LATENCY``; the ``ftdi_sio`` driver sets the timer to 1 ms) is asked on open; the
  timer is read back from sysfs and torque is refused while it reads more than 1 ms.
* **MX-28 firmware 27 (0x1B) or newer.** Older firmware has 1024 positions per turn; ROBOTIS's
  demo (``Linux/project/demo/main.cpp``) exits with "Upgrade MX-28's firmware to version
  27(0x1B) or higher" (``Linux/project/firmware_installer``). Such a servo stays offline.

``DARWIN_SYSFS_ROOT`` moves the sysfs root (tests give a fake FTDI device tree);
``DARWIN_PROC_ROOT`` the procfs root (a test plays a daemon that cannot see the other holder).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import select
import sys
import threading
import time
from pathlib import Path

from schemas.errors import PortInUseError, SlowPortError

MIN_MX28_FIRMWARE = 27  # 0x1B
MAX_LATENCY_MS = 1
# How long the daemon listens before its first byte: several of another master's 8 ms polls.
LISTEN_S = 0.1


def sysfs_root() -> Path:
    return Path(os.environ.get("DARWIN_SYSFS_ROOT", "/sys"))


def latency_timer_path(port_name: str) -> Path:
    dev = os.path.basename(os.path.realpath(port_name))
    return sysfs_root() / "bus" / "usb-serial" / "devices" / dev / "latency_timer"


def latency_timer_ms(port_name: str) -> int | None:
    """The FTDI USB latency timer of a ttyUSB port (ms), or None if it has none."""
    try:
        return int(latency_timer_path(port_name).read_text().strip())
    except (OSError, ValueError):
        return None


def check_latency(port_name: str) -> None:
    """Refuse a latency timer above 1 ms, naming the fix."""
    timer = latency_timer_ms(port_name)
    if timer is not None and timer > MAX_LATENCY_MS:
        dev = os.path.basename(os.path.realpath(port_name))
        raise SlowPortError(
            f"the USB latency timer of {port_name} is {timer} ms (needs {MAX_LATENCY_MS}): every "
            f"reply would come late, torque refused; set it: echo 1 | sudo tee "
            f"/sys/bus/usb-serial/devices/{dev}/latency_timer (for good: `darwin service` "
            "installs the udev rule; docs/troubleshooting.md#latency-timer)"
        )


def _pty_index(path: str) -> int | None:
    name = os.path.basename(path)
    return int(name) if path.startswith("/dev/pts/") and name.isdigit() else None


def proc_root() -> str:
    return os.environ.get("DARWIN_PROC_ROOT", "/proc")


def port_holders(port_name: str, proc: str | None = None) -> list[tuple[int, str]]:
    """Other processes with ``port_name`` open, as (PID, command line); not this process and
    not the pty's master holder (the emulator). Only the processes whose ``/proc/PID/fd`` this
    user may read: a root process is invisible to a daemon that is not root."""
    proc = proc or proc_root()
    real = os.path.realpath(port_name)
    index = _pty_index(real)
    holders: list[tuple[int, str]] = []
    me = os.getpid()
    for entry in os.scandir(proc):
        if not entry.name.isdigit() or int(entry.name) == me:
            continue
        fd_dir = f"{entry.path}/fd"
        try:
            fds = os.listdir(fd_dir)
        except OSError:
            continue  # gone, or not ours to look at
        holds = master = False
        for fd in fds:
            try:
                target = os.readlink(f"{fd_dir}/{fd}")
            except OSError:
                continue
            if target == real:
                holds = True
            elif index is not None and target in ("/dev/ptmx", "/dev/pts/ptmx"):
                master = master or _fd_tty_index(entry.path, fd) == index
        if holds and not master:
            holders.append((int(entry.name), _command(entry.path)))
    return holders


def _fd_tty_index(pid_dir: str, fd: str) -> int | None:
    with contextlib.suppress(OSError, ValueError):
        for line in Path(f"{pid_dir}/fdinfo/{fd}").read_text().splitlines():
            if line.startswith("tty-index:"):
                return int(line.split(":", 1)[1])
    return None


def _command(pid_dir: str) -> str:
    try:
        raw = Path(f"{pid_dir}/cmdline").read_bytes()
    except OSError:
        return "?"
    return raw.replace(b"\0", b" ").decode(errors="replace").strip()[:80] or "?"


def check_holders(port_name: str) -> None:
    """Refuse to start while another process has the port open, naming it and the fix."""
    holders = port_holders(port_name)
    if holders:
        pid, cmd = holders[0]
        more = f" (and {len(holders) - 1} more)" if len(holders) > 1 else ""
        raise PortInUseError(
            f"serial port {port_name} is held open by PID {pid} ({cmd}){more}: two programs "
            f"would drive one bus; stop it (`sudo kill {pid}`; ROBOTIS's demo starts from "
            "/etc/rc.local: remove it there) and start again"
        )


def refuse_unasked(port_name: str, count: int) -> None:
    """Refuse to drive a bus on which ``count`` bytes arrived while the daemon was silent."""
    if count:
        raise PortInUseError(
            f"{count} bytes arrived on {port_name} while the daemon had sent nothing: another "
            "program is driving this bus (ROBOTIS's demo starts from /etc/rc.local: remove it "
            "there, or stop it) and start again"
        )


class HolderWatch:
    """Looks at the port's holders in a thread of its own (the ``/proc`` walk costs
    milliseconds, 2.6 M instructions with a hundred processes: never in the tick); :meth:`new`
    hands each new holder over once.

    Where Linux's inotify is there, the walk runs when someone opens or closes the port (the
    kernel says so) and at no other time; elsewhere every ``interval`` s."""

    def __init__(self, port_name: str, interval: float) -> None:
        self.port_name = port_name
        self.interval = interval
        self._seen: set[int] = {pid for pid, _ in port_holders(port_name)}
        self._new: list[tuple[int, str]] = []
        self.current: list[tuple[int, str]] = []  # the other holders at the last look
        self.walks = 0  # looks since the start
        self._lock = threading.Lock()
        self._walked = threading.Condition(self._lock)
        self._stop = threading.Event()
        self._wake_r, self._wake_w = os.pipe()
        self._opens = OpenWatch.create(port_name)  # None: no inotify, walk by the clock
        self._thread = threading.Thread(target=self._run, name="port-holders", daemon=True)
        self._thread.start()

    @property
    def by_event(self) -> bool:
        """Whether the port's opens and closes drive the walk (inotify), not the clock."""
        return self._opens is not None

    def _run(self) -> None:
        try:
            if self._opens is None:
                while not self._stop.wait(self.interval):
                    self._walk()
            else:
                self._run_by_event(self._opens)
        finally:
            for fd in (self._wake_r, self._wake_w):
                with contextlib.suppress(OSError):
                    os.close(fd)
            if self._opens is not None:
                self._opens.close()

    def _run_by_event(self, opens: OpenWatch) -> None:
        # The kernel says "opened" just before the opener's descriptor is in /proc/PID/fd, so
        # each event is looked at now and once more a moment later.
        again: float | None = None
        while not self._stop.is_set():
            timeout = None if again is None else max(0.0, again - time.monotonic())
            ready, _, _ = select.select([opens.fd, self._wake_r], [], [], timeout)
            if self._wake_r in ready:
                return
            if opens.fd in ready:
                opens.drain()
                self._walk()
                again = time.monotonic() + _LOOK_AGAIN_S
            elif again is not None and time.monotonic() >= again:
                again = None
                self._walk()

    def _walk(self) -> None:
        with contextlib.suppress(OSError):
            found = port_holders(self.port_name)
            self.current = found
            with self._lock:
                for pid, cmd in found:
                    if pid not in self._seen:
                        self._seen.add(pid)
                        self._new.append((pid, cmd))
        with self._walked:
            self.walks += 1
            self._walked.notify_all()

    def wait_walks(self, n: int, timeout: float) -> bool:
        """Wait until the holders have been looked at ``n`` times since the start."""
        with self._walked:
            return self._walked.wait_for(lambda: self.walks >= n, timeout)

    def new(self) -> list[tuple[int, str]]:
        """The holders that appeared since the last call (a lock-free check first: per tick)."""
        if not self._new:
            return []
        with self._lock:
            out, self._new = self._new, []
        return out

    def close(self) -> None:
        self._stop.set()
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")


# A second look this long after an open or close: its descriptor is in /proc by then.
_LOOK_AGAIN_S = 0.2
_IN_OPEN, _IN_CLOSE_WRITE, _IN_CLOSE_NOWRITE = 0x20, 0x08, 0x10


class OpenWatch:
    """inotify on one file: readable when a process opens or closes it (any path to the same
    device: a udev symlink, the pty's link). Linux only; :meth:`create` says None elsewhere."""

    def __init__(self, fd: int) -> None:
        self.fd = fd

    @classmethod
    def create(cls, path: str) -> OpenWatch | None:
        if not sys.platform.startswith("linux"):
            return None
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            fd = libc.inotify_init1(os.O_NONBLOCK | os.O_CLOEXEC)
        except (OSError, AttributeError):
            return None
        if fd < 0:
            return None
        mask = _IN_OPEN | _IN_CLOSE_WRITE | _IN_CLOSE_NOWRITE
        if libc.inotify_add_watch(fd, os.fsencode(path), mask) < 0:
            os.close(fd)
            return None
        return cls(fd)

    def drain(self) -> None:
        with contextlib.suppress(BlockingIOError):
            while os.read(self.fd, 4096):
                pass

    def close(self) -> None:
        with contextlib.suppress(OSError):
            os.close(self.fd)


def firmware_refusal(dxl_id: int, name: str, firmware: int) -> str | None:
    """The one line refusing a servo with pre-4096-position firmware, or None."""
    if 0 < firmware < MIN_MX28_FIRMWARE:
        return (
            f"servo {dxl_id} ({name}) has MX-28 firmware {firmware} (< {MIN_MX28_FIRMWARE}, "
            "1024 positions per turn): left offline, torque refused; upgrade it to 27 (0x1B) "
            "or newer (ROBOTIS's Linux/project/firmware_installer or RoboPlus Dynamixel Wizard)"
        )
    return None
