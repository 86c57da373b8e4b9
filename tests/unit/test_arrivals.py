"""A client's wait tests every message that arrived since it started, not only the newest."""

from __future__ import annotations

import threading

import pytest

from clients.arrivals import RECENT, Arrivals
from schemas.errors import CommandTimeoutError


def test_a_message_followed_at_once_by_another_is_found() -> None:
    log = Arrivals()
    log.add("events", "loop slow")
    since = log.count("events")
    log.add("events", "busy: refused")
    log.add("events", "loop recovered")  # newest, before the waiter looked
    assert log.wait("events", lambda m: "busy" in m, 1.0, since) == "busy: refused"


def test_only_messages_after_the_moment_count() -> None:
    log = Arrivals()
    log.add("events", "busy: old")
    with pytest.raises(CommandTimeoutError, match="no 'events' message"):
        log.wait("events", lambda m: "busy" in m, 0.05)  # from now: the old one is not news
    assert log.wait("events", lambda m: "busy" in m, 0.05, since=0) == "busy: old"
    assert log.wait("events", lambda m: True, 0.05, since=log.count("events") - 1) == "busy: old"


def test_topics_are_apart() -> None:
    log = Arrivals()
    since = log.count("status")
    log.add("events", "x")
    with pytest.raises(CommandTimeoutError):
        log.wait("status", lambda m: True, 0.05, since)


def test_a_waiter_wakes_for_a_message_from_another_thread() -> None:
    log = Arrivals()
    since = log.count("joints")
    adder = threading.Thread(target=lambda: [log.add("joints", i) for i in range(5)])
    adder.start()
    assert log.wait("joints", lambda m: m == 3, 5.0, since) == 3
    adder.join()


def test_more_than_it_keeps_leaves_the_newest() -> None:
    log = Arrivals()
    since = log.count("imu")
    for i in range(RECENT + 10):
        log.add("imu", i)
    assert log.wait("imu", lambda m: True, 0.05, since) == 10  # the oldest it still holds
