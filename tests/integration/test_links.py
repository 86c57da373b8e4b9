"""Links that fail, in Linux network namespaces (``tests/fixtures/netns.py``): real ``darwin up``
in a ``robot`` namespace, real notebook clients (:mod:`tests.fixtures.link_agent`) in
``operator`` and ``observer`` namespaces, each on its own veth link through a ``router``
namespace; links are cut with ``ip link set … down`` and impaired with ``tc netem``.

Times are printed (``-s`` shows them), never asserted: the tests assert what happens.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Iterator

import pytest

from robot_daemon.arbiter.lease import SILENT
from tests.fixtures.netns import Agent, Network, network, unavailable
from tests.fixtures.system import RunningSystem

REASON = unavailable()
pytestmark = pytest.mark.skipif(REASON is not None, reason=REASON or "")

WAIT = 15.0  # generous: the machine may be loaded; never a measure of speed
ENDED_BY_LINK = (SILENT, "holder vanished")  # heartbeat or liveliness: both mean "not heard"


@pytest.fixture
def net() -> Iterator[Network]:
    with network() as n:
        yield n


def robot_up(net: Network, *extra: str) -> RunningSystem:
    """``darwin up`` (emulator + daemon) in the robot namespace, listening on its link."""
    name = f"t{uuid.uuid4().hex[:10]}"
    return net.darwin(
        "robot", "up", "--robot", name, "--no-gateway", "--camera", "none",
        "--no-wire-timing", *extra,
    )  # fmt: skip


def direct(net: Network) -> tuple[RunningSystem, str]:
    system = robot_up(net, "--listen", f"tcp/{net.addr('robot')}:7447")
    return system, system.endpoint


def walking(agent: Agent, robot: str, fresh: bool = False) -> dict:
    return agent.request(
        "wait_status", path="motion.walking.walking", equals=True, timeout=WAIT, fresh=fresh
    )


def assert_safe_stop(observer: Agent, holder: str, cut: float, what: str) -> None:
    """The lease of ``holder`` ended because it was not heard, the walk ended its step and the
    legs hold the pose; prints how long after ``cut`` each happened."""
    ended = observer.request(
        "wait_event", kind="lease", data={"holder": None}, since=cut, timeout=WAIT
    )
    assert ended["data"]["reason"] in ENDED_BY_LINK, ended
    assert holder in ended["message"], ended
    stopped = observer.request(
        "wait_event", kind="walk", data={"state": "stopped"}, since=cut, timeout=WAIT
    )
    status = observer.request(
        "wait_status", path="motion.walking.walking", equals=False, timeout=WAIT, fresh=True
    )
    assert status["lease"] is None
    assert "walking" not in status["motion"]["owners"].values()  # handed back: holding the pose
    print(
        f"\n{what}: lease ended {ended['stamp'] - cut:.2f} s after the cut "
        f"({ended['data']['reason']}), walk stopped {stopped['stamp'] - cut:.2f} s after it"
    )


def test_operator_link_cut_safe_stop_then_client_reconnects(net: Network) -> None:
    system, ep = direct(net)
    operator = net.agent("operator", ep, system.robot, "op-cut")
    observer = net.agent("observer", ep, system.robot, "watcher")
    operator.call("acquire")
    operator.call("walk", x=0.05)
    walking(observer, system.robot)

    cut = time.time()
    net.link_down("operator")
    assert_safe_stop(observer, "op-cut", cut, "operator link cut")

    # The link comes back: the same Robot object reconnects by itself and sees the robot.
    back = time.time()
    net.link_up("operator")
    # What was queued for it before the cut may arrive first: wait for the robot as it is now.
    seen = operator.request("wait_status", path="lease", equals=None, timeout=WAIT, fresh=True)
    assert seen["motion"]["walking"]["walking"] is False
    assert operator.call("alive") is True
    operator.call("acquire")  # its commands reach the arbiter again, with a new lease
    applied = operator.call("led", head=[255, 0, 0])
    assert applied["head"][0] > 200
    print(f"operator sees status again {seen['received'] - back:.2f} s after the link is back")
