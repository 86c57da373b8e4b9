"""A client's watch on the daemon's announced versions: it judges status messages only, and a
UI hears of them whenever a status says them, not only within a wait at connect (on a loaded
machine the first status came after the TUI's 3 s wait and the skew was never shown)."""

from __future__ import annotations

import logging

import msgpack
import pytest

from clients.protocol_watch import ProtocolWatch
from schemas.errors import IncompatibleProtocolError
from schemas.messages import Imu, Status, encode
from schemas.versions import PROTOCOL_VERSION


def test_another_message_on_the_status_key_is_no_announcement() -> None:
    watch = ProtocolWatch("this client")
    imu = Imu(gyro=[0.0] * 3, accel=[0.0, 0.0, 9.81], gyro_raw=[512] * 3, accel_raw=[512] * 3)
    watch.observe(encode(imu))  # no protocol in it: it would read as an unannounced daemon
    watch.refuse()  # nothing refused
    watch.observe(encode(Status(state="running", robot="r", protocol=list(PROTOCOL_VERSION))))
    assert watch.wait(0.0) is None


def test_a_status_of_another_major_is_still_refused() -> None:
    watch = ProtocolWatch("this client")
    other = {"v": 99, "type": "status", "robot": "r", "protocol": [PROTOCOL_VERSION[0] + 1, 0]}
    watch.observe(msgpack.packb(other))
    with pytest.raises(IncompatibleProtocolError, match="speaks protocol"):
        watch.refuse()


MAJOR, MINOR = PROTOCOL_VERSION


def status(protocol: tuple[int, int]) -> dict[str, object]:
    return {"type": "status", "robot": "r1", "protocol": list(protocol), "version": "9.9.9"}


def test_a_listener_hears_an_announcement_that_comes_after_the_wait() -> None:
    watch = ProtocolWatch("this test")
    assert watch.wait(0.0) is None  # nothing announced yet: the wait at connect gives up
    heard: list[tuple[str | None, IncompatibleProtocolError | None]] = []
    watch.listen(lambda w, e: heard.append((w, e)))
    assert heard == []
    watch.observe(status((MAJOR, MINOR + 1)))
    watch.observe(status((MAJOR, MINOR + 1)))  # the same announcement again: heard once
    assert len(heard) == 1 and heard[0][1] is None
    assert heard[0][0] is not None and "upgrade this client" in heard[0][0]
    watch.observe(status((MAJOR + 1, 0)))  # upgraded under us to another major
    assert len(heard) == 2 and isinstance(heard[1][1], IncompatibleProtocolError)


def test_a_listener_added_later_hears_what_was_already_announced() -> None:
    watch = ProtocolWatch("this test")
    watch.observe(status((MAJOR, MINOR + 1)))
    heard: list[str | None] = []
    watch.listen(lambda w, e: heard.append(w))
    assert len(heard) == 1 and heard[0] is not None and "upgrade this client" in heard[0]


def test_the_skew_is_logged_before_a_waiter_wakes_and_not_at_all_for_a_one_line_program(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """A program that refuses in one line prints it when its wait wakes: the watch's own log
    record (from Zenoh's thread) must come before, never after (it was the last line of
    `darwin record` on a loaded machine); a program that says it itself is not logged for."""
    watch = ProtocolWatch("this client")
    refused_when_logged: list[bool] = []

    class Probe(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            refused_when_logged.append(watch.error is not None)

    probe = Probe()
    logging.getLogger("clients.protocol_watch").addHandler(probe)
    try:
        watch.observe(status((MAJOR + 1, 0)))
    finally:
        logging.getLogger("clients.protocol_watch").removeHandler(probe)
    assert refused_when_logged == [False]
    caplog.clear()
    quiet = ProtocolWatch("darwin record", log_skew=False)
    quiet.observe(status((MAJOR + 1, 0)))
    quiet.observe(status((MAJOR, MINOR + 1)))
    assert quiet.warning is not None and not caplog.records
