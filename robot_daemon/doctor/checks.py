"""The doctor's checks: small functions from facts to one :class:`Check` each, so the daemon's
bring-up and other tools can share them. None of them touches the bus; what they judge is
gathered by :mod:`robot_daemon.doctor.probe` (a direct bus scan or the daemon's status)."""

from __future__ import annotations

import os
import shutil
import stat
import time
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from pathlib import Path

from config.robotis_offsets import NotImported
from robot_daemon.bus.chains import first_missing

OK, WARN, FAIL, SKIP = "ok", "warn", "fail", "skip"


@dataclass(frozen=True)
class Check:
    """One check's result: its status, what it found and the fix."""

    name: str
    status: str  # ok | warn | fail | skip
    detail: str
    fix: str = ""

    def line(self) -> str:
        head = f"{self.status.upper():<4}  {self.name}: {self.detail}"
        return f"{head} — fix: {self.fix}" if self.fix and self.status in (WARN, FAIL) else head

    def as_dict(self) -> dict[str, str]:
        return asdict(self)


@dataclass(frozen=True)
class Holder:
    """A process that holds the serial port."""

    pid: int
    command: str


def serial_device(path: str) -> Check:
    if not os.path.exists(path):
        return Check(
            "serial",
            FAIL,
            f"{path} does not exist",
            "plug in the robot's USB cable (`ls /dev/ttyUSB*`) or pass --port; "
            "on the simulator start `darwin sim`",
        )
    real = os.path.realpath(path)
    if not stat.S_ISCHR(os.stat(real).st_mode):
        return Check("serial", FAIL, f"{path} is not a character device", "pass the tty, --port")
    return Check("serial", OK, f"{path} present" + (f" ({real})" if real != path else ""))


def _pty_index(real: str) -> int | None:
    head, _, tail = real.rpartition("/")
    return int(tail) if head == "/dev/pts" and tail.isdigit() else None


def port_holders(path: str, proc_root: Path = Path("/proc"), me: int | None = None) -> list[Holder]:
    """Every other process with ``path`` open (scanning ``/proc/*/fd``). The process holding the
    master side of the same pseudo-terminal (the emulator) is the wire, not a bus master."""
    real = os.path.realpath(path)
    index = _pty_index(real)
    me = os.getpid() if me is None else me
    holders: list[Holder] = []
    for entry in proc_root.iterdir():
        if not entry.name.isdigit() or int(entry.name) == me:
            continue
        holds = master = False
        try:
            for fd in (entry / "fd").iterdir():
                try:
                    target = os.readlink(fd)
                except OSError:
                    continue
                if target == real:
                    holds = True
                elif index is not None and target == "/dev/ptmx":
                    info = (entry / "fdinfo" / fd.name).read_text()
                    master = master or f"tty-index:\t{index}\n" in info
        except OSError:  # gone, or not ours to look at
            continue
        if holds and not master:
            try:
                cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode().strip()
            except OSError:
                cmd = "?"
            holders.append(Holder(int(entry.name), cmd or "?"))
    return holders


def port_holder_check(path: str, holders: list[Holder], daemon_running: bool) -> Check:
    ours = ("darwin", "robot_daemon")  # `darwin daemon`, `python -m robot_daemon.launch.cli daemon`
    others = [h for h in holders if not (daemon_running and any(w in h.command for w in ours))]
    if not others:
        who = "held by the daemon" if holders else "not held by another process"
        return Check("port holder", OK, f"{path} {who}")
    listed = ", ".join(f"PID {h.pid} ({h.command[:60]})" for h in others)
    return Check(
        "port holder",
        FAIL,
        f"{path} is open in {listed}",
        f"stop it (`kill {others[0].pid}`; ROBOTIS's demo starts from /etc/rc.local, "
        "ModemManager and brltty grab ttyUSB devices: `sudo systemctl mask ModemManager brltty`)",
    )


def latency_timer_path(path: str, sysfs_root: Path = Path("/sys")) -> Path:
    dev = os.path.basename(os.path.realpath(path))
    return sysfs_root / "bus" / "usb-serial" / "devices" / dev / "latency_timer"


def latency_timer(path: str, sysfs_root: Path = Path("/sys")) -> Check:
    timer = latency_timer_path(path, sysfs_root)
    try:
        ms = int(timer.read_text().strip())
    except (OSError, ValueError):
        return Check("latency timer", SKIP, f"{path} has no FTDI latency timer (not a ttyUSB)")
    if ms <= 1:
        return Check("latency timer", OK, f"{ms} ms")
    return Check(
        "latency timer",
        FAIL,
        f"{ms} ms: the CM-730's reply, last of every bulk read, arrives late",
        f"echo 1 | sudo tee {timer}  (or `darwin service install` for a udev rule)",
    )


def bus_answers(port: str, baud: int, answered_at: int | None, devices: int) -> Check:
    if answered_at is None:
        return Check(
            "bus",
            FAIL,
            f"nothing answers on {port} at any standard baud rate",
            "check the robot is switched on and the CM-730's USB cable; "
            "press the CM-730's reset button",
        )
    if answered_at != baud:
        return Check(
            "bus",
            FAIL,
            f"devices answer at {answered_at} bps, not at the configured {baud}",
            f"set [daemon] baud = {answered_at}, or give the devices {baud} (`darwin servo "
            "replace` for one servo)",
        )
    return Check("bus", OK, f"{devices} device(s) answer at {baud} bps")


@dataclass(frozen=True)
class ServoInfo:
    """One servo as the probe saw it: ID, model and firmware."""

    id: int
    model: str
    firmware: int | None  # None: not known (the daemon's reader may not see it)


def servos(
    expected: Iterable[int], found: Mapping[int, ServoInfo], min_firmware: int
) -> list[Check]:
    """One line for the servos that answer as expected, one per servo that does not, and one
    per chain where a break hides servos, naming the first missing ID."""
    expected = list(expected)
    out: list[Check] = []
    missing = [i for i in expected if i not in found]
    present = [found[i] for i in expected if i in found]
    wrong = [s for s in present if s.model != "MX-28"]
    old = [s for s in present if s.firmware is not None and s.firmware < min_firmware]
    good = len(present) - len(wrong) - len(old)
    firmwares = sorted({s.firmware for s in present if s.firmware is not None})
    out.append(
        Check(
            "servos",
            OK if not missing and not wrong and not old else FAIL,
            f"{good}/{len(expected)} MX-28 with firmware ≥ {min_firmware}"
            + (f" (firmware {', '.join(map(str, firmwares))})" if firmwares else ""),
        )
    )
    for s in wrong:
        out.append(
            Check(f"servo {s.id}", FAIL, f"is a {s.model}, not an MX-28", "fit an MX-28 there")
        )
    for s in old:
        out.append(
            Check(
                f"servo {s.id}",
                FAIL,
                f"firmware {s.firmware} < {min_firmware} (older firmware uses 1024 positions)",
                "update it with ROBOTIS's R+ Manager / Dynamixel Wizard firmware recovery",
            )
        )
    for branch, (first, lost) in first_missing(missing).items():
        behind = ", ".join(map(str, lost[1:]))
        out.append(
            Check(
                f"chain {branch}",
                FAIL,
                f"ID {first} does not answer"
                + (f", nor the {len(lost) - 1} behind it ({behind})" if len(lost) > 1 else ""),
                f"check servo {first} and the cable into it from the servo before it "
                "(a break there hides everything behind it)",
            )
        )
    on_chains = {i for _, lost in first_missing(missing).values() for i in lost}
    for i in (i for i in missing if i not in on_chains):
        out.append(Check(f"servo {i}", FAIL, "does not answer", f"check servo {i}'s cable"))
    return out


def voltage(volts: float | None, warn_v: float, fail_v: float) -> Check:
    if volts is None:
        return Check("voltage", SKIP, "not read (the CM-730 did not answer)")
    if volts < fail_v:
        return Check("voltage", FAIL, f"{volts:.1f} V (< {fail_v} V)", "charge or swap the battery")
    if volts < warn_v:
        return Check("voltage", WARN, f"{volts:.1f} V (< {warn_v} V)", "charge the battery soon")
    return Check("voltage", OK, f"{volts:.1f} V")


def temperatures(temps: Mapping[int, float], warn_c: float, fail_c: float) -> Check:
    if not temps:
        return Check("temperature", SKIP, "no servo answered")
    hottest = max(temps, key=lambda i: temps[i])
    t = temps[hottest]
    hot = sorted(i for i, c in temps.items() if c >= warn_c)
    detail = f"hottest ID {hottest} at {t:.0f} °C"
    if t >= fail_c:
        return Check(
            "temperature",
            FAIL,
            f"{detail}; ≥ {warn_c:.0f} °C: {', '.join(map(str, hot))}",
            "torque off and let the servos cool; check for a joint pushing against something",
        )
    if t >= warn_c:
        return Check("temperature", WARN, detail, "let the servos rest before walking")
    return Check("temperature", OK, detail)


def clock(
    now: float, min_year: int, daemon_stamp: float | None = None, skew_s: float = 2.0
) -> Check:
    year = time.gmtime(now).tm_year
    if year < min_year:
        return Check(
            "clock",
            FAIL,
            f"this computer says {time.strftime('%Y-%m-%d', time.gmtime(now))}",
            "set the time (`sudo timedatectl set-ntp true`, or `sudo date -s …`): recordings "
            "and certificates need it",
        )
    if daemon_stamp is not None and abs(now - daemon_stamp) > skew_s:
        return Check(
            "clock",
            WARN,
            f"the daemon's clock is {daemon_stamp - now:+.1f} s from this computer's",
            "run NTP on both (`sudo timedatectl set-ntp true`)",
        )
    return Check("clock", OK, time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(now)))


def disk(path: Path, min_mb: float) -> Check:
    try:
        free = shutil.disk_usage(path).free / 1e6
    except OSError as exc:
        return Check("disk", FAIL, f"cannot look at {path}: {exc.strerror}", "create it")
    if free < min_mb:
        return Check(
            "disk",
            FAIL,
            f"{free:.0f} MB free at {path} (< {min_mb:.0f} MB for recordings)",
            "delete or move old recordings",
        )
    return Check("disk", OK, f"{free:.0f} MB free at {path}")


def loop_headroom(loop: Mapping[str, float] | None, min_headroom: float) -> Check:
    if not loop or not loop.get("tick_ms"):
        return Check("loop", SKIP, "the daemon is not running (no loop to measure)")
    tick, work = float(loop["tick_ms"]), float(loop.get("work_p99_ms", 0.0))
    headroom = 1.0 - work / tick
    overruns = int(loop.get("overruns", 0))
    detail = f"p99 work {work:.2f} ms of {tick:g} ms: {headroom:.0%} headroom, {overruns} overruns"
    if headroom < min_headroom:
        return Check(
            "loop", WARN, detail, "stop other programs on the robot (vision, recording to SD)"
        )
    return Check("loop", OK, detail)


def zenoh_reach(endpoint: str, robot: str, reached: bool, state: str | None) -> Check:
    if reached:
        return Check("zenoh", OK, f"daemon {robot} answers at {endpoint} (state {state})")
    return Check(
        "zenoh",
        WARN,
        f"no daemon {robot} at {endpoint}; the bus was scanned directly",
        "start it (`darwin daemon --port …`, or `darwin up`) or check --connect/--robot",
    )


def versions(client: str, daemon: str | None) -> Check:
    if daemon is None:
        return Check("versions", OK, f"client {client}; daemon not running or not telling")
    if daemon != client:
        return Check(
            "versions",
            WARN,
            f"client {client}, daemon {daemon}",
            "install the same version on both",
        )
    return Check("versions", OK, f"client and daemon {client}")


def robotis_offsets(path: str, missing: NotImported | None) -> Check:
    """ROBOTIS's own offsets on the robot (its ``config.ini``) against the daemon's config."""
    if missing is None:
        return Check("offsets", OK, f"{path} agrees with this config")
    return Check("offsets", WARN, missing.detail, missing.fix)
