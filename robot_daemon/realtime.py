"""Real-time scheduling for the motion thread, as the ROBOTIS framework gives its motion timer.

Under the normal scheduler a busy robot PC (camera, vision, SSH sessions) can wake the motion
thread milliseconds late, and a late tick sends its goals late. ``SCHED_FIFO`` at a modest
priority wakes it first. ``SCHED_RESET_ON_FORK`` keeps every thread and process it starts
(ball vision, a sound player) at normal priority, so only the loop itself runs real-time; the
kernel's real-time throttling still leaves the rest of the machine a share of each second.
"""

from __future__ import annotations

import os

from schemas.errors import ConfigError

MAX_PRIORITY = 99


def check_priority(value: object, setting: str) -> int:
    """``value`` as a priority (0 = off, 1..99), or ``ConfigError`` naming ``setting``."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_PRIORITY:
        raise ConfigError(
            f"{setting} must be 0 (off) or a whole number 1..{MAX_PRIORITY}, not {value!r}"
        )
    return value


def enter_realtime(
    priority: int, thread: str = "the motion thread", setting: str = "daemon.realtime_priority"
) -> str | None:
    """Make the calling thread real-time at ``priority`` (1..99; 0 leaves it as it is).

    Returns None on success, else a warning that says why and how to allow it: running
    without real-time priority is slower to wake, not unsafe, so the program goes on.
    ``thread`` and ``setting`` name the thread and its setting in that warning."""
    if check_priority(priority, "realtime_priority") == 0:
        return None
    if not hasattr(os, "sched_setscheduler"):
        return "real-time scheduling is not available on this platform; the loop runs normally"
    policy = os.SCHED_FIFO | getattr(os, "SCHED_RESET_ON_FORK", 0)
    try:
        os.sched_setscheduler(0, policy, os.sched_param(priority))
    except PermissionError:
        return (
            f"{thread} may not run real-time (priority {priority}): allow it for the "
            "robot's user in /etc/security/limits.conf (e.g. `robot - rtprio 50`) or run it "
            f"as root; set {setting} = 0 to silence this"
        )
    except OSError as exc:
        return f"could not make {thread} real-time (priority {priority}): {exc}"
    return None


def current_policy() -> str:
    """The calling thread's scheduling policy, for ``status`` ("fifo", "other", …)."""
    if not hasattr(os, "sched_getscheduler"):
        return "unknown"
    policy = os.sched_getscheduler(0) & ~getattr(os, "SCHED_RESET_ON_FORK", 0)
    names = {os.SCHED_FIFO: "fifo", os.SCHED_RR: "rr", os.SCHED_OTHER: "other"}
    return names.get(policy, str(policy))


# The kernel's PM QoS interface: while a process holds this file open with a latency written
# to it, no core enters an idle state slower than that to leave (Documentation/power/pm_qos).
CPU_DMA_LATENCY = "/dev/cpu_dma_latency"


def check_latency(value: object, setting: str) -> int:
    """``value`` as a wake-up latency in µs (-1 = leave the idle states alone), or
    ``ConfigError`` naming ``setting``."""
    if isinstance(value, bool) or not isinstance(value, int) or not -1 <= value <= 1_000_000:
        raise ConfigError(f"{setting} must be -1 (off) or a latency in µs (0..1000000), not "
                          f"{value!r}")
    return value


def hold_cpu_latency(us: int, path: str = CPU_DMA_LATENCY) -> tuple[int | None, str | None]:
    """Keep the CPU out of idle states slower than ``us`` to leave, for as long as the returned
    descriptor stays open (-1: do nothing). Returns (descriptor, None) or (None, a warning):
    without it the loop wakes later and colder, it is not unsafe, so the daemon goes on."""
    if check_latency(us, "cpu_dma_latency_us") < 0:
        return None, None
    try:
        fd = os.open(path, os.O_WRONLY)
    except OSError as exc:
        return None, (
            f"could not hold the CPU's wake-up latency at {us} µs ({path}: {exc.strerror}): "
            "run the daemon as root (the robot's service does) or boot with "
            "intel_idle.max_cstate=2; set daemon.cpu_dma_latency_us = -1 to silence this"
        )
    try:
        os.write(fd, int(us).to_bytes(4, "little", signed=True))
    except OSError as exc:
        os.close(fd)
        return None, f"could not hold the CPU's wake-up latency at {us} µs ({path}: {exc})"
    return fd, None
