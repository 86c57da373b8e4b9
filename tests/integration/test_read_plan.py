"""The read plan (``[daemon] servo_reads_per_tick``): the CM-730 every tick, the servos in turn;
on the simulated rig (daemon bus code, emulator, simulated wire)."""

from __future__ import annotations

import copy

from config.loader import load_all
from robot_daemon.bus.read_plan import servos_to_read
from robot_daemon.bus.tables import CM730_ID, SERVO_IDS
from tests.fixtures.sim_rig import SimRig


def test_every_servo_by_default_and_a_share_in_turn() -> None:
    online = list(SERVO_IDS)
    assert servos_to_read(online, {5}, 3, 0) == online
    seen: set[int] = set()
    for tick in range(5):
        chosen = servos_to_read(online, {20}, tick, 4)
        assert 20 in chosen and len(chosen) <= 5 and chosen == sorted(chosen)
        seen |= set(chosen)
    assert seen == set(online)  # five ticks of four: every servo once


def test_a_share_reads_the_cm730_every_tick_and_every_servo_in_turn() -> None:
    settings = copy.deepcopy(load_all())
    settings["daemon"] = {**settings.get("daemon", {}), "servo_reads_per_tick": 4}
    rig = SimRig(seed=5, settings=settings)
    asked: list[list[int]] = []
    bulk = rig.bus.dxl.bulk_read  # type: ignore[union-attr]

    def spy(blocks):  # the blocks each tick asks for, then the real bulk read
        blocks = list(blocks)
        asked.append([b[0] for b in blocks])
        return bulk(blocks)

    rig.bus.dxl.bulk_read = spy  # type: ignore[union-attr,method-assign]
    rig.run(0.008 * 10)
    assert all(CM730_ID in ids for ids in asked)
    assert all(len(ids) <= 4 + 1 + 1 for ids in asked)  # share, a slow read, the CM-730
    assert set().union(*asked) >= set(SERVO_IDS)
    assert rig.bus.counters.missing_replies == 0
    assert all(rig.bus.state.online[j] for j in SERVO_IDS)  # nobody blamed for not being asked
