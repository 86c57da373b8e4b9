"""A client's watch on the daemon's announced versions judges status messages only."""

from __future__ import annotations

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
