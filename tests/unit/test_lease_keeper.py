"""The client's lease renewals (clients/lease_keeper.py): sent at a fixed rate whatever the
replies do, so a slow reply never makes the holder look silent to the daemon."""

from __future__ import annotations

import threading

from clients.lease_keeper import IN_FLIGHT, LeaseKeeper
from schemas.errors import CommandTimeoutError


def test_a_slow_reply_does_not_hold_back_the_next_renewal() -> None:
    first_waits = threading.Event()  # released only once a second renewal has been sent
    calls: list[int] = []
    second = threading.Event()
    lock = threading.Lock()

    def renew() -> None:
        with lock:
            calls.append(len(calls))
            n = len(calls)
        if n == 1:
            assert first_waits.wait(10.0), "the second renewal never came while the first waited"
        elif n == 2:
            second.set()

    keeper = LeaseKeeper(renew, "t", period=0.01)
    keeper.hold("secret")
    try:
        assert second.wait(10.0), "the next renewal waited for the first one's reply"
    finally:
        first_waits.set()
        keeper.drop()


def test_renewals_awaiting_replies_are_bounded_and_failures_do_not_stop_them() -> None:
    release = threading.Event()
    started = threading.Semaphore(0)
    failed_once = threading.Event()
    count = 0
    lock = threading.Lock()

    def renew() -> None:
        nonlocal count
        with lock:
            count += 1
            n = count
        if n == 1:
            failed_once.set()
            raise CommandTimeoutError("lease: no answer within 1 s")  # a lost reply: go on
        started.release()
        release.wait(10.0)

    keeper = LeaseKeeper(renew, "t", period=0.005)
    keeper.hold("secret")
    try:
        for _ in range(IN_FLIGHT):
            assert started.acquire(timeout=10.0), "renewals stopped after a failed one"
        # All IN_FLIGHT wait for their reply: no more are started until one comes back.
        assert not started.acquire(timeout=0.3)
        release.set()
        assert started.acquire(timeout=10.0), "renewals did not go on after the replies came"
    finally:
        release.set()
        keeper.drop()
    assert failed_once.is_set()


def test_drop_waits_for_the_renewals_awaiting_their_reply() -> None:
    # A renewal left inside Zenoh's query when a script ends comes back into a finalizing
    # Python and aborts the process (clients/lease_keeper.py, drop): drop waits for it.
    started = threading.Event()
    release = threading.Event()
    finished = threading.Event()

    def renew() -> None:
        started.set()
        release.wait(10.0)
        finished.set()

    keeper = LeaseKeeper(renew, "t", period=0.005)
    keeper.hold("secret")
    assert started.wait(10.0)
    timer = threading.Timer(0.2, release.set)  # the reply comes while drop is under way
    timer.start()
    try:
        keeper.drop()
        assert finished.is_set(), "drop returned while a renewal still awaited its reply"
        assert not [t for t in threading.enumerate() if t.name.startswith("lease-renewal-t")]
    finally:
        release.set()
        timer.join()
