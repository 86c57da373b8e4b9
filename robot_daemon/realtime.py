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


def enter_realtime(priority: int) -> str | None:
    """Make the calling thread real-time at ``priority`` (1..99; 0 leaves it as it is).

    Returns None on success, else a warning that says why and how to allow it: running
    without real-time priority is slower to wake, not unsafe, so the daemon goes on."""
    if check_priority(priority, "realtime_priority") == 0:
        return None
    if not hasattr(os, "sched_setscheduler"):
        return "real-time scheduling is not available on this platform; the loop runs normally"
    policy = os.SCHED_FIFO | getattr(os, "SCHED_RESET_ON_FORK", 0)
    try:
        os.sched_setscheduler(0, policy, os.sched_param(priority))
    except PermissionError:
        return (
            f"the motion thread may not run real-time (priority {priority}): allow it for the "
            "robot's user in /etc/security/limits.conf (e.g. `robot - rtprio 50`) or run the "
            "daemon as root; set daemon.realtime_priority = 0 to silence this"
        )
    except OSError as exc:
        return f"could not make the motion thread real-time (priority {priority}): {exc}"
    return None


def current_policy() -> str:
    """The calling thread's scheduling policy, for ``status`` ("fifo", "other", …)."""
    if not hasattr(os, "sched_getscheduler"):
        return "unknown"
    policy = os.sched_getscheduler(0) & ~getattr(os, "SCHED_RESET_ON_FORK", 0)
    names = {os.SCHED_FIFO: "fifo", os.SCHED_RR: "rr", os.SCHED_OTHER: "other"}
    return names.get(policy, str(policy))
