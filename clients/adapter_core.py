"""The policy every protocol adapter (legacy gateway, ROS 2, Foxglove) applies to the lease.

An adapter drives the robot for clients that know nothing of the lease: it takes the lease on
demand when it is free, gives it back when its clients go quiet, stops a walk they started when
its commands stop coming (the deadman), and says "someone else holds the lease" once per burst
of refused commands rather than once per command. :class:`AdapterCore` holds that policy and
nothing else: no Zenoh, no threads, no event loop. The adapter passes the time in (``now``,
from whatever clock it runs on: ``time.monotonic()``, ``loop.time()``, a test's counter), asks
it what to do, does it with its own Commander or Robot, and tells it what happened::

    if core.before_command(now):        # the lease is needed and not held: take it
        robot.acquire(); core.acquired(now)
    robot.walk(x, y, turn); core.walk(now)
    ...
    for action in core.tick(now):       # from a timer: STOP_WALK and/or RELEASE
        ...

So asyncio adapters and threaded ones share one tested policy (``tests/unit/test_adapter_core``).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class Action(Enum):
    STOP_WALK = "stop_walk"  # no walk command for ``deadman`` s: stop the walk it started
    RELEASE = "release"  # no command for ``idle_release`` s: give the lease taken on demand back


@dataclass
class AdapterCore:
    """The lease and deadman policy of one adapter client (see the module's text).

    ``idle_release``: seconds without a command before a lease taken on demand is given back
    (None or <= 0: never). ``deadman``: seconds without a walk command before the walk is
    stopped (None: never). ``burst_gap``: seconds without a command that end a burst, so the
    next refusal is reported again (None: ``deadman``, or 0.5 s).
    """

    idle_release: float | None = None
    deadman: float | None = None
    burst_gap: float | None = None

    def __post_init__(self) -> None:
        self.holding = False  # we hold the lease (as far as we know)
        self.auto = False  # ... and took it on demand (an explicit acquire is never given back)
        self.walking = False
        self._last_cmd = float("-inf")
        self._last_walk = float("-inf")
        self._refused_burst = False
        self._last_refusal = float("-inf")
        if self.burst_gap is None:
            self.burst_gap = self.deadman if self.deadman is not None else 0.5

    # -- commands ----------------------------------------------------------------------------
    def before_command(self, now: float, needs_lease: bool = True) -> bool:
        """A command arrives (activity); True when the adapter must take the lease first."""
        self.active(now)
        return needs_lease and not self.holding

    def active(self, now: float, until: float | None = None) -> None:
        """Activity now, or (something playing, e.g. a trajectory) until ``until``."""
        self._last_cmd = max(self._last_cmd, now if until is None else max(now, until))

    def acquired(self, now: float, auto: bool = True) -> bool:
        """The lease was taken (``auto``: on demand). True when it was not held before."""
        was = self.holding
        self.holding = True
        self.auto = auto if not was else self.auto and auto
        self.active(now)
        return not was

    def lost(self) -> None:
        """The arbiter says we do not hold the lease (busy, or it ended it): take it next time."""
        self.holding = False

    def refused(self, now: float) -> bool:
        """Someone else holds the lease: True for the first refusal of a burst (report it)."""
        self.lost()
        if self.burst_gap is not None and now - self._last_refusal > self.burst_gap:
            self._refused_burst = False  # a quiet gap ended the last burst, ticked or not
        self._last_refusal = now
        self.active(now)
        if self._refused_burst:
            return False
        self._refused_burst = True
        return True

    def walk(self, now: float) -> None:
        """A non-zero walk command was sent: the deadman watches it from now."""
        self.walking = True
        self._last_walk = now

    def walk_seen(self, now: float) -> None:
        """A walk command arrived (even a zero or refused one): the deadman hears it."""
        self._last_walk = now

    def walk_stopped(self) -> bool:
        """The walk was stopped (or ended): True if one was going."""
        was, self.walking = self.walking, False
        return was

    def released(self) -> bool:
        """The lease was given back (or is being): True if it was held."""
        was = self.holding
        self.holding = self.auto = self.walking = False
        return was

    # -- time --------------------------------------------------------------------------------
    def tick(self, now: float) -> list[Action]:
        """What is due at ``now``: STOP_WALK (deadman), RELEASE (idle). The adapter does them
        and calls :meth:`walk_stopped` / :meth:`released`; RELEASE implies the walk stops too."""
        actions = []
        if self.walking and self.deadman is not None and now - self._last_walk >= self.deadman:
            actions.append(Action.STOP_WALK)
        if self.burst_gap is not None and now - self._last_cmd > self.burst_gap:
            self._refused_burst = False  # the next refused command is a new burst
        idle = self._idle_limit()
        if idle is not None and now - self._last_cmd >= idle:
            actions.append(Action.RELEASE)
        return actions

    def _idle_limit(self) -> float | None:
        """The idle time after which the lease is given back, if it is to be."""
        idle = self.idle_release
        if self.holding and self.auto and idle is not None and idle > 0:
            return idle
        return None

    def next_due(self) -> float | None:
        """When :meth:`tick` may next have something to do (for a one-shot timer)."""
        times = []
        if self.walking and self.deadman is not None:
            times.append(self._last_walk + self.deadman)
        idle = self._idle_limit()
        if idle is not None:
            times.append(self._last_cmd + idle)
        return min(times) if times else None
