"""Bad input from Foxglove clients: each gets an error, and the server and the robot carry on."""

from __future__ import annotations

import socket
import struct
import subprocess
from collections.abc import Iterator

import pytest

from schemas.session import free_tcp_port
from tests.fixtures.system import RunningSystem, darwin_command, start_system
from tests.foxglove_ws import WAIT, FoxgloveClient
from tests.integration.test_foxglove_server import address

pytestmark = pytest.mark.timeout(240)


@pytest.fixture(scope="module")
def fox() -> Iterator[tuple[RunningSystem, str]]:
    listen = f"127.0.0.1:{free_tcp_port()}"
    with start_system(gateway=False, extra_args=["--foxglove", "--foxglove-listen", listen]) as s:
        yield s, address(s, "foxglove")


def still_serving(system: RunningSystem, url: str) -> None:
    """A new Foxglove client gets live joints and the robot's loop keeps ticking."""
    with FoxgloveClient.open(url) as fc, system.robot_client(name="check") as robot:
        fc.subscribe("/joints")
        first = fc.take("/joints")["tick"]
        assert fc.take("/joints", lambda m: m["tick"] > first)
        # (degraded for a moment should a loaded machine starve a few bulk reads)
        robot.wait_for("status", lambda s: s.state == "running", WAIT)
    assert system.alive


def test_garbage_frames_and_unknown_channels(fox: tuple[RunningSystem, str]) -> None:
    system, url = fox
    with FoxgloveClient.open(url) as fc:
        fc.send({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 999999}]})
        fc.status_matching("999999")
        fc.ws.send(b"\x99garbage")
        fc.ws.send("{not json")
        fc.send({"op": "no-such-op"})
    still_serving(system, url)


def test_unknown_services_and_bad_requests(fox: tuple[RunningSystem, str]) -> None:
    system, url = fox
    with FoxgloveClient.open(url) as fc:
        fc.subscribe("/status")
        enc = b"json"
        fc.ws.send(bytes([0x02]) + struct.pack("<III", 4242, 1, len(enc)) + enc + b"{}")
        kind, message = fc.until(lambda c: c.responses.get(1))
        assert kind == "fail", message
        kind, message = fc.call("/action", b"{not json", 2)
        assert kind == "fail" and "not JSON" in message
        kind, message = fc.call("/torque", {"enable": "yes"}, 3)
        assert kind == "fail" and "enable" in message
        kind, message = fc.call("/lease", {"op": "acquire", "evil": 1}, 4)
        assert kind == "fail" and "evil" in message
        # Moving needs the lease: the arbiter's refusal reaches the caller.
        kind, message = fc.call("/action", {"page": 1}, 5)
        assert kind == "fail" and "lease" in message.lower()
    still_serving(system, url)


def test_out_of_range_parameters_and_bad_teleop(fox: tuple[RunningSystem, str]) -> None:
    system, url = fox
    with FoxgloveClient.open(url) as fc, system.robot_client(name="check") as robot:
        fc.subscribe("/status")
        assert fc.call("/lease", {"op": "acquire"}, 1)[0] == "ok"
        before = robot.command("walk_params")["params"]["period_time"]
        reply = fc.set_parameters(
            [{"name": "walk/period_time", "value": 1e9, "type": "float64"}], "r1"
        )
        assert reply[0]["value"] == before
        assert "period_time" in fc.status_matching("walking parameters not changed")["message"]
        fc.set_parameters([{"name": "walk/no_such", "value": 1}], "r2")
        fc.status_matching("no_such")
        fc.set_parameters([{"name": "other", "value": 1}], "r3")
        fc.status_matching("'other'")
        assert robot.command("walk_params")["params"]["period_time"] == before
        fc.advertise(3, "/cmd_vel", "geometry_msgs/Twist")
        fc.ws.send(bytes([0x01]) + struct.pack("<I", 3) + b"\xff\xfe not json")
        fc.status_matching("teleop: not JSON")
        fc.publish(3, {"linear": {"x": "fast"}})
        fc.status_matching("x must be a number")
        fc.ws.send(bytes([0x01]) + struct.pack("<I", 77) + b"{}")  # never advertised
        status = robot.wait_for("status", lambda s: True, WAIT)
        assert not status.motion.get("walking", {}).get("walking")
        assert fc.call("/lease", {"op": "release"}, 2)[0] == "ok"
    still_serving(system, url)


@pytest.mark.parametrize("command", ["foxglove", "web"])
def test_a_busy_port_is_one_line_naming_the_fix(
    fox: tuple[RunningSystem, str], command: str
) -> None:
    system, _ = fox
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        target = ["--connect", system.endpoint, "--robot", system.robot]
        out = subprocess.run(
            darwin_command(command, *target, "--listen", f"127.0.0.1:{port}"),
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert out.returncode == 1 and out.stdout == ""
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and f"127.0.0.1:{port}" in lines[0] and "--listen" in lines[0], lines
