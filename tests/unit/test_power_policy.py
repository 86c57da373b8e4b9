"""The graded battery and heat policy (robot_daemon/power_policy.py) on synthetic time: a ramp
walks ok → warn → sit → off one event each, spikes shorter than the hold never trip it, values
inside the hysteresis never flap, recovery needs the hysteresis."""

from __future__ import annotations

import pytest

from robot_daemon.power_policy import (
    LEVELS,
    HeatSettings,
    PowerPolicy,
    PowerSettings,
    load_settings,
)


def _policy() -> PowerPolicy:
    return PowerPolicy(PowerSettings(), HeatSettings(), {1: "r_sho_pitch", 2: "l_sho_pitch"})


def _run(policy: PowerPolicy, volts: list[float], temps: float = 40.0) -> list[tuple[str, str]]:
    out = []
    for i, v in enumerate(volts):  # 10 Hz
        out += [(k, lvl) for k, lvl, _, _ in policy.update(v, {1: temps, 2: 40.0}, i / 10)]
    return out


def test_a_ramp_down_walks_warn_sit_off_once_each_despite_spikes() -> None:
    ramp = [12.0] * 30
    for v in (10.9, 10.4, 9.9):
        ramp += [v] * 30 + [12.0, 12.0] + [v] * 30  # a spike of recovery shorter than the hold
    walk = [11.5 if i % 3 else 9.5 for i in range(60)]  # current spikes while walking
    assert _run(_policy(), [12.0] * 10 + walk) == []
    assert _run(_policy(), ramp) == [("power", "warn"), ("power", "sit"), ("power", "off")]


def test_recovery_needs_the_hysteresis_and_does_not_flap() -> None:
    policy = _policy()
    assert _run(policy, [10.9] * 30) == [("power", "warn")]
    wobble = [11.0, 11.2, 10.95, 11.25] * 30  # around the threshold, inside the hysteresis
    assert _run(policy, wobble) == []
    assert _run(policy, [11.4] * 30) == [("power", "ok")]


def test_a_heating_servo_raises_its_alarm_and_cools_down() -> None:
    policy = _policy()
    events = _run(policy, [12.0] * 30, temps=72.0)
    assert events == [("heat", "sit")]
    assert policy.heat_info()["alarms"] == [1]
    assert policy.heat_info()["hottest"][0] == {"id": 1, "name": "r_sho_pitch", "celsius": 72.0}
    assert _run(policy, [12.0] * 30, temps=67.0) == []  # inside the 5 °C hysteresis
    assert _run(policy, [12.0] * 30, temps=60.0) == [("heat", "warn")]
    assert _run(policy, [12.0] * 30, temps=50.0) == [("heat", "ok")]


def test_settings_out_of_order_are_refused() -> None:
    with pytest.raises(ValueError, match="warn_v > sit_v > off_v"):
        load_settings({"power": {"warn_v": 10.0}})
    with pytest.raises(Exception, match="nearest known"):
        load_settings({"heat": {"warn": 60}})


def test_the_daemon_refuses_a_bad_power_table_in_one_line(tmp_path) -> None:
    from tests.fixtures.system import run_darwin

    config = tmp_path / "bad.toml"
    config.write_text("[power]\nwarn_v = 10.0\n")
    done = run_darwin("daemon", "--port", str(tmp_path / "none"), "--config", str(config))
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "warn_v > sit_v > off_v" in lines[0], done.stderr
    config.write_text("[heat]\nwarm_c = 60\n")
    done = run_darwin("daemon", "--port", str(tmp_path / "none"), "--config", str(config))
    assert done.returncode == 1 and "[heat] has an unknown setting 'warm_c'" in done.stderr


def test_the_quiet_shortcut_gives_every_transition_of_the_full_update() -> None:
    # While every servo is at level 0 with nothing pending, update() skips the servos when
    # none reaches warn: over random walks of temperature around every threshold (spikes
    # shorter and longer than the hold, recoveries, servos going offline) it gives the same
    # transitions, at the same times, and the same levels as updating every servo each time.
    import random

    heat = HeatSettings()
    names = {j: f"s{j}" for j in range(1, 21)}
    for seed in range(30):
        rng = random.Random(seed)
        fast, full = (PowerPolicy(PowerSettings(), heat, names) for _ in range(2))
        top = heat.warn_c + 2.0 if seed % 2 else heat.warn_c - 10.0  # mostly quiet, or not
        temps = {j: rng.uniform(30.0, top) for j in names}
        for step in range(600):
            for j in temps:
                temps[j] += rng.choice([0.0, 0.0, rng.uniform(-2.0, 2.0)])
                if rng.random() < 0.01:
                    temps[j] = rng.choice([40.0, 40.0, heat.warn_c, heat.sit_c + 1.0,
                                           heat.off_c + 1.0])
            online = {j: t for j, t in temps.items() if rng.random() > 0.02}
            full._heat_quiet = False  # always the update of every servo
            want = full.update(12.0, dict(online), step / 10)
            assert fast.update(12.0, dict(online), step / 10) == want
            assert [g.level for g in fast.servos.values()] == [
                g.level for g in full.servos.values()
            ]
            assert fast.heat_info() == full.heat_info() == _heat_info_by_definition(full)


def _heat_info_by_definition(policy: PowerPolicy) -> dict[str, object]:
    """heat_info as first written: every servo asked, the hottest by a Python key."""
    hot = sorted(policy.temps.items(), key=lambda kv: -kv[1])[: policy.heat_settings.hottest]
    return {
        "level": LEVELS[max((g.level for g in policy.servos.values()), default=0)],
        "hottest": [{"id": j, "name": policy.names[j], "celsius": c} for j, c in hot],
        "alarms": [j for j, g in policy.servos.items() if g.level > 0],
    }


def test_the_hottest_keep_id_order_among_equals() -> None:
    names = {j: f"s{j}" for j in range(1, 9)}
    policy = PowerPolicy(PowerSettings(), HeatSettings(), names)
    temps = {1: 40.0, 2: 51.0, 3: 40.0, 4: 51.0, 5: 45.0, 6: 51.0, 7: 30.0, 8: 45.0}
    policy.update(12.0, temps, 0.0)
    info = policy.heat_info()
    assert info == _heat_info_by_definition(policy)
    assert [h["id"] for h in info["hottest"]] == [2, 4, 6]
