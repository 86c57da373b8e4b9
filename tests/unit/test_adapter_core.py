"""The adapters' one lease policy (clients.adapter_core), driven by an injected clock."""

from __future__ import annotations

from clients.adapter_core import Action, AdapterCore


def test_the_lease_is_taken_on_demand_once_and_not_for_commands_that_need_none() -> None:
    core = AdapterCore(idle_release=10.0)
    assert core.before_command(0.0, needs_lease=False) is False
    assert core.before_command(0.0) is True  # needed and not held: take it
    assert core.acquired(0.0) is True  # newly taken
    assert core.before_command(1.0) is False  # held: no second acquire
    assert core.acquired(1.0) is False  # taken again (re-acquire): not new


def test_a_lease_taken_on_demand_is_given_back_after_idle_and_not_before() -> None:
    core = AdapterCore(idle_release=10.0)
    core.before_command(0.0)
    core.acquired(0.0)
    core.before_command(5.0)  # activity moves the deadline
    assert core.next_due() == 15.0
    assert core.tick(14.9) == []
    assert core.tick(15.0) == [Action.RELEASE]
    assert core.released() is True
    assert core.tick(100.0) == [] and core.next_due() is None
    assert core.before_command(101.0) is True  # taken again on the next command


def test_something_playing_counts_as_activity_until_it_ends() -> None:
    core = AdapterCore(idle_release=10.0)
    core.before_command(0.0)
    core.acquired(0.0)
    core.active(1.0, until=30.0)  # a trajectory of 29 s
    assert core.tick(35.0) == []
    assert core.tick(40.0) == [Action.RELEASE]


def test_an_explicitly_taken_lease_is_never_given_back_for_idleness() -> None:
    core = AdapterCore(idle_release=10.0)
    core.acquired(0.0, auto=False)
    assert core.tick(1000.0) == [] and core.next_due() is None
    core.before_command(1000.0)
    core.acquired(1000.0)  # an on-demand take while held explicitly stays explicit
    assert core.tick(2000.0) == []


def test_idle_release_off_keeps_the_lease() -> None:
    for idle in (None, 0.0):
        core = AdapterCore(idle_release=idle)
        core.before_command(0.0)
        core.acquired(0.0)
        assert core.tick(1e6) == [] and core.next_due() is None


def test_a_lost_lease_is_taken_again_on_the_next_command() -> None:
    core = AdapterCore(idle_release=10.0)
    core.before_command(0.0)
    core.acquired(0.0)
    core.lost()
    assert core.tick(100.0) == []  # nothing to give back
    assert core.before_command(100.0) is True


def test_the_deadman_stops_a_walk_after_silence_only() -> None:
    core = AdapterCore(deadman=0.5)
    core.walk(0.0)
    assert core.next_due() == 0.5
    core.walk_seen(0.4)  # a walk command (even a zero one) keeps it alive
    assert core.tick(0.8) == []
    assert core.tick(0.9) == [Action.STOP_WALK]
    assert core.walk_stopped() is True
    assert core.tick(5.0) == [] and core.walk_stopped() is False


def test_release_and_deadman_together() -> None:
    core = AdapterCore(idle_release=2.0, deadman=0.5)
    core.before_command(0.0)
    core.acquired(0.0)
    core.walk(0.0)
    assert core.tick(2.0) == [Action.STOP_WALK, Action.RELEASE]
    core.released()
    assert core.walking is False and core.holding is False


def test_someone_else_holding_the_lease_is_reported_once_per_burst() -> None:
    core = AdapterCore(idle_release=10.0, deadman=0.5)
    t = 0.0
    reports = []
    for _ in range(20):  # a burst at 20 Hz
        core.before_command(t)
        reports.append(core.refused(t))
        core.tick(t)
        t += 0.05
    assert reports.count(True) == 1 and reports[0] is True
    assert core.holding is False
    core.tick(t + 0.4)  # a short pause: the same burst
    assert core.refused(t + 0.4) is False
    core.tick(t + 1.0)  # silence longer than the gap: the next refusal is a new burst
    assert core.refused(t + 1.0) is True


def test_the_burst_gap_is_its_own_setting_when_given() -> None:
    core = AdapterCore(burst_gap=2.0)
    assert core.refused(0.0) is True
    core.tick(1.5)
    assert core.refused(1.5) is False
    core.tick(3.6)
    assert core.refused(3.6) is True


def test_a_quiet_gap_ends_a_burst_even_without_a_timer() -> None:
    core = AdapterCore(deadman=0.5)  # an adapter that ticks only while it walks
    assert core.before_command(0.0) and core.refused(0.0) is True
    assert core.before_command(0.3) and core.refused(0.3) is False  # the same burst
    assert core.before_command(2.0) and core.refused(2.0) is True  # a new one, no tick between
