"""Orchestrate on the simulator: status 1 when the list starts, 0 when it ends or is stopped."""

from __future__ import annotations

from typing import Any

from tests.fixtures.system import RunningSystem
from tests.legacy_client import LegacyClient


def types_by_kind(robot) -> dict[str, int]:
    """The legacy type table, as every client can fetch it (the `behaviours` query)."""
    return {kind: int(t) for t, kind in robot.command("behaviours")["types"].items()}


def chor(status) -> dict[str, Any]:
    return status.choreography or status.motion.get("choreography") or {}


def client(system: RunningSystem, **kwargs: Any) -> LegacyClient:
    assert system.gateway is not None
    return LegacyClient(*system.gateway, timeout=30.0, **kwargs)


def test_three_items_play_to_the_end(robot_system: RunningSystem) -> None:
    with robot_system.robot_client(name="observer") as robot:
        robot.wait_for("status", lambda s: s.lease is None, timeout=30.0, fresh=False)
        t = types_by_kind(robot)
        items = [
            {"page": 211, "type": t["led"]},  # eyes green
            {"page": 1, "type": t["action"]},  # action page 1 (stand)
            {"page": 220, "type": t["pause"]},  # pause 1 s
        ]
        with client(robot_system, order="little") as c:
            c.send({"orchestrate": items})
            assert c.recv_until(lambda m: "orchestrate" in m or "error" in m) == {
                "orchestrate": {"status": 1}
            }
            assert c.recv_until(lambda m: "orchestrate" in m or "error" in m) == {
                "orchestrate": {"status": 0}
            }
            robot.wait_for("status", lambda s: chor(s).get("last_result") == "finished", 30.0)
            st = robot.wait_for("status", lambda s: not chor(s).get("playing"), 30.0, fresh=False)
            assert st.leds.get("eye") == [0, 248, 0]


def test_stop_mid_list_ends_early(robot_system: RunningSystem) -> None:
    with robot_system.robot_client(name="observer") as robot:
        robot.wait_for("status", lambda s: s.lease is None, timeout=30.0, fresh=False)
        t = types_by_kind(robot)
        items = [{"page": 220, "type": t["pause"]}] * 20  # twenty pauses of a second each
        with client(robot_system, order="ascii", counted=True) as c:
            c.send({"orchestrate": items})
            assert c.recv_until(lambda m: "orchestrate" in m or "error" in m) == {
                "orchestrate": {"status": 1}
            }
            robot.wait_for("status", lambda s: chor(s).get("playing") is True, 30.0, fresh=False)
            c.send({"orchestrate": {"status": 0}})
            assert c.recv_until(lambda m: "orchestrate" in m or "error" in m) == {
                "orchestrate": {"status": 0}
            }
            # The daemon says the list was stopped, not played to its end.
            robot.wait_for("status", lambda s: chor(s).get("last_result") == "stopped", 30.0)
            # Exactly one status 0: the stop's answer, not a second one from the end event.
            c.send({"marker": 1})
            c.recv_error()
            zeros = [m for m in c.received if m == {"orchestrate": {"status": 0}}]
            assert len(zeros) == 1


def test_unknown_type_is_a_clear_error(robot_system: RunningSystem) -> None:
    with client(robot_system) as c:
        c.send({"orchestrate": [{"page": 1, "type": 999}]})
        err = c.recv_error()
        assert err["code"] == "unknown" and "type 999" in err["message"]
        assert not [m for m in c.received if "orchestrate" in m]
