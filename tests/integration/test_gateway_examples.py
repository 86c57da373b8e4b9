"""Every example of the report's appendix A, verbatim, in every framing convention, against
the gateway that `darwin up` started (emulator, daemon, real Zenoh, real TCP)."""

from __future__ import annotations

import math

import pytest

from schemas import units
from tests.fixtures.system import RunningSystem
from tests.legacy_client import APPENDIX_A_CLIENT_EXAMPLES, CONVENTIONS, LegacyClient

EX = dict(
    zip(
        (
            "monitor_off",
            "monitor_accel",
            "operate",
            "led",
            "orchestrate",
            "orchestrate_stop",
            "walk",
            "playball",
        ),
        APPENDIX_A_CLIENT_EXAMPLES,
        strict=True,
    )
)


def connect(system: RunningSystem, order: str, counted: bool) -> LegacyClient:
    assert system.gateway is not None, system.output()
    host, port = system.gateway
    return LegacyClient(host, port, order=order, counted=counted, timeout=30.0)


def walking(status) -> bool:
    return bool(status.motion.get("walking", {}).get("walking"))


def lease_free(robot) -> None:
    """The previous test's legacy client is gone: wait until the arbiter saw its token go."""
    robot.wait_for("status", lambda s: s.lease is None, timeout=30.0, fresh=False)


@pytest.mark.parametrize(("order", "counted"), CONVENTIONS)
def test_appendix_a_examples_in_every_convention(
    robot_system: RunningSystem, order: str, counted: bool
) -> None:
    with robot_system.robot_client(name="observer") as robot:
        lease_free(robot)
        with connect(robot_system, order, counted) as c:
            # Monitor: all off sends nothing; accelerometer on sends only the accelerometer.
            c.send(EX["monitor_off"])
            c.send(EX["monitor_accel"])
            msg = c.recv_until(lambda m: bool(m.get("monitor")))
            assert list(msg["monitor"]) == ["accelerometer"]
            accel = msg["monitor"]["accelerometer"]
            assert len(accel) == 3 and 8.0 < math.hypot(*accel) < 11.5  # gravity, m/s²

            # Operate: joint 3 to 27°, converted to rad at servo resolution.
            c.send(EX["operate"])
            want = units.raw_to_rad(units.deg_to_raw(27))
            robot.wait_for("joints", lambda j: abs(j.goal[j.id.index(3)] - want) < 1e-3, 30.0)

            # Led 26: the forehead LED, in the CM-730's 15-bit colour.
            c.send(EX["led"])
            rgb = list(units.color_word_to_rgb(units.rgb_to_color_word(182, 35, 28)))
            robot.wait_for("status", lambda s: s.leds.get("head") == rgb, 30.0)

            # Orchestrate: page 325 is not in the action library: a clear error, no start.
            c.send(EX["orchestrate"])
            err = c.recv_error()
            assert "325" in err["message"], err
            # Orchestrate stop: always answered with status 0.
            c.send(EX["orchestrate_stop"])
            assert c.recv_until(lambda m: "orchestrate" in m) == {"orchestrate": {"status": 0}}

            # Walk forward, then stop (walk is the example with x = 10).
            c.send(EX["walk"])
            robot.wait_for("status", walking, 30.0)
            c.send({"walk": {"a": 0, "stop": 1, "x": 0, "y": 0}})
            robot.wait_for("status", lambda s: not walking(s), 30.0)

            # Playball status 1 = stop (decision): answered with status 0.
            c.send(EX["playball"])
            assert c.recv_until(lambda m: "playball" in m) == {"playball": {"status": 0}}

            # Nothing the client sent was rejected apart from page 325.
            errors = [m["error"] for m in c.received if "error" in m]
            assert errors == [err], errors

            # Playball status 0 = start: this system has no camera, so a clear error and no
            # status reply.
            c.send({"playball": {"status": 0}})
            err = c.recv_error()
            assert err["code"] == "unavailable" and "camera" in err["message"], err
            assert [m for m in c.received if "playball" in m] == [{"playball": {"status": 0}}]
