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
  every ``daemon.holder_check_s`` (:class:`HolderWatch`); a new one halts the motion and is
  reported (two masters sync-writing every 8 ms make the servos chatter and fight).
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
import os
import threading
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
    """Looks at the port's holders every ``interval`` s in a thread of its own (the ``/proc``
    walk costs milliseconds: never in the tick); :meth:`new` hands each new holder over once."""

    def __init__(self, port_name: str, interval: float) -> None:
        self.port_name = port_name
        self.interval = interval
        self._seen: set[int] = {pid for pid, _ in port_holders(port_name)}
        self._new: list[tuple[int, str]] = []
        self.current: list[tuple[int, str]] = []  # the other holders at the last look
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="port-holders", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self.interval):
            with contextlib.suppress(OSError):
                found = port_holders(self.port_name)
                self.current = found
                with self._lock:
                    for pid, cmd in found:
                        if pid not in self._seen:
                            self._seen.add(pid)
                            self._new.append((pid, cmd))

    def new(self) -> list[tuple[int, str]]:
        """The holders that appeared since the last call (a lock-free check first: per tick)."""
        if not self._new:
            return []
        with self._lock:
            out, self._new = self._new, []
        return out

    def close(self) -> None:
        self._stop.set()


def firmware_refusal(dxl_id: int, name: str, firmware: int) -> str | None:
    """The one line refusing a servo with pre-4096-position firmware, or None."""
    if 0 < firmware < MIN_MX28_FIRMWARE:
        return (
            f"servo {dxl_id} ({name}) has MX-28 firmware {firmware} (< {MIN_MX28_FIRMWARE}, "
            "1024 positions per turn): left offline, torque refused; upgrade it to 27 (0x1B) "
            "or newer (ROBOTIS's Linux/project/firmware_installer or RoboPlus Dynamixel Wizard)"
        )
    return None
