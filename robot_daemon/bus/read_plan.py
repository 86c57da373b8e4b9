"""Which servos the tick's bulk read asks for: all of them (the default), or a round-robin
share when the computer cannot afford every servo every tick (``[daemon] servo_reads_per_tick``).

The CM-730 (IMU, buttons, voltage) is read every tick whatever the plan, as ROBOTIS's framework
does: since r55 its 8 ms ``MotionManager::Process`` bulk-reads only the CM-730 unless a module
asks for servo feedback. What a share costs: a servo's present position, speed and load are up
to ``ceil(online / share)`` ticks old. The gait is open-loop (it plays goals), and balance and the
fall monitor run on the CM-730's gyro and accelerometer, so neither changes; what slows is what
reads servo feedback: the published joints (stale entries), alarm bits, and noticing an offline
servo (``offline_after_misses`` counts the reads it missed, so it takes that many of its turns).
"""

from __future__ import annotations


def servos_to_read(online: list[int], slow: set[int], tick: int, share: int) -> list[int]:
    """The online servos to read this tick, in bus order: every one when ``share`` is 0 or
    covers them all, else ``share`` of them in turn, plus the ones due a slow read."""
    if share <= 0 or share >= len(online):
        return online
    n = len(online)
    start = (tick * share) % n
    chosen = {online[(start + k) % n] for k in range(share)} | slow
    return [j for j in online if j in chosen]
