"""One reader for every settings table: a config table → its dataclass, refusing unknown keys
(naming the nearest known one) and values of the wrong type, for every settings module."""

from __future__ import annotations

from dataclasses import dataclass, field

import pytest

from config.loader import load_all, nearest, ranged, refuse_unknown, section_to
from gateway.settings import load_settings
from robot_daemon.arbiter.lease import Lease
from robot_daemon.arbiter.throttle import ArbiterLimits
from robot_daemon.motion.ball.settings import BallPlaySettings
from robot_daemon.motion.fall import FallMonitor
from robot_daemon.motion.head import HeadLimits
from robot_daemon.motion.sound import SoundPlayer
from robot_daemon.motion.walking.params import check
from robot_daemon.vision.ball_finder import FinderSettings
from schemas.errors import ConfigError


@dataclass(frozen=True)
class Inner:
    gain: float = 1.0


@dataclass(frozen=True)
class Table:
    label: str
    count: int = 1
    rate: float = 2.0
    enabled: bool = True
    tilts: tuple[float, ...] = (0.0,)
    rgb: tuple[int, int, int] = (1, 2, 3)
    start: tuple[float, float] | None = None
    ids: list[int] = field(default_factory=list)
    inner: Inner = Inner()


def test_a_table_becomes_its_dataclass_with_values_converted_to_the_field_types() -> None:
    t = section_to(
        Table,
        {"label": "x", "rate": 4, "tilts": [1, 2.5], "rgb": [4, 5, 6], "start": [1, 2]}
        | {"ids": [7], "inner": {"gain": 3}},
        "t",
    )
    assert t == Table("x", 1, 4.0, True, (1.0, 2.5), (4, 5, 6), (1.0, 2.0), [7], Inner(3.0))
    assert isinstance(t.rate, float) and isinstance(t.inner.gain, float)
    assert section_to(Table, {}, "t", label="given").label == "given"


@pytest.mark.parametrize(
    ("values", "message"),
    [
        (
            {"label": "x", "cuont": 2},
            r"\[t\] has an unknown setting 'cuont' \(nearest known: 'count'\)",
        ),
        ({"label": "x", "inner": {"gian": 2}}, r"\[t.inner\] .*'gian' \(nearest known: 'gain'\)"),
        ({"label": "x", "rate": "fast"}, r"\[t\] rate = 'fast' should be a number"),
        ({"label": "x", "count": 2.5}, r"count = 2.5 should be an integer"),
        ({"label": "x", "count": True}, r"count = True should be an integer"),
        ({"label": "x", "enabled": 1}, r"enabled = 1 should be true or false"),
        ({"label": 3}, r"label = 3 should be a string"),
        ({"label": "x", "tilts": ["a"]}, r"tilts = \['a'\] should be a list of numbers"),
        ({"label": "x", "rgb": [1, 2]}, r"rgb = \[1, 2\] should be a list of 3 integers"),
        ({"label": "x", "start": 3}, r"start = 3 should be a list of 2 numbers"),
        ({"label": "x", "inner": 3}, r"inner = 3 should be a table"),
        ({"count": 2}, r"\[t\] is incomplete: it needs label"),
    ],
)
def test_a_bad_table_is_one_clear_error_naming_the_key(values: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        section_to(Table, values, "t")


@dataclass(frozen=True)
class Limits:
    rate: float = ranged(2.0, 0.5, 10)
    count: int = ranged(1, 1)
    floor: float = ranged(0.0, None, 0)


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"rate": 11}, r"\[t\] rate must be within 0.5..10, not 11.0"),
        ({"count": 0}, r"\[t\] count must be at least 1, not 0"),
        ({"floor": 1}, r"\[t\] floor must be at most 0, not 1.0"),
    ],
)
def test_a_value_outside_the_range_its_field_declares_is_refused(
    values: dict, message: str
) -> None:
    assert section_to(Limits, {"rate": 10, "count": 5, "floor": -3}, "t") == Limits(10.0, 5, -3.0)
    with pytest.raises(ConfigError, match=message):
        section_to(Limits, values, "t")


def test_skipped_keys_belong_to_another_reader_and_given_fields_are_not_read() -> None:
    assert section_to(Table, {"label": "x", "finder": {}}, "t", skip=("finder",)).label == "x"
    with pytest.raises(ConfigError, match="unknown setting 'label'"):
        section_to(Table, {"label": "x"}, "t", label="given")


def test_nearest_prefers_a_case_only_difference_and_honours_the_cutoff() -> None:
    assert nearest("COUNT", ["count", "counts"]) == "count"
    assert nearest("speed", ["max_rate", "burst"]) is not None  # always the nearest one…
    assert nearest("speed", ["max_rate", "burst"], cutoff=0.6) is None  # …unless asked
    with pytest.raises(ConfigError, match=r"\[w\] has an unknown setting 'b'.*; known: a"):
        refuse_unknown({"a": 1, "b": 2}, ["a"], "w")


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (
            lambda c: BallPlaySettings.from_config(c["ballplay"] | {"kiks": 2}),
            r"\[ballplay\].*'kicks'",
        ),
        (
            lambda c: BallPlaySettings.from_config(c["ballplay"] | {"head": {"pan_limit": 60}}),
            r"\[ballplay.head\].*'pan_limit_deg'",
        ),
        (
            lambda c: FinderSettings.from_config(c["ballplay"] | {"finder": {"min_fil": 0.5}}),
            r"\[ballplay.finder\].*'min_fill'",
        ),
        (
            lambda c: FinderSettings.from_config(c["ballplay"] | {"camera": {"fov_h": 60.0}}),
            r"\[ballplay.camera\].*'fov_h_deg'",
        ),
        (
            lambda c: ArbiterLimits.from_config({"queue_sise": 3}),
            r"\[daemon.arbiter\].*'queue_size'",
        ),
        (lambda c: ArbiterLimits.from_config({"queue_size": 0}), "queue_size must be a positive"),
        (lambda c: HeadLimits.from_config({"pan_max": 60.0}), r"\[head\].*'pan_max_deg'"),
        (lambda c: Lease.from_config({"idle_timout": 3.0}), r"\[daemon.lease\].*'idle_timeout'"),
        (lambda c: FallMonitor(c["imu"], {"recovr": False}), r"\[fall\].*'recover'"),
        (lambda c: FallMonitor(c["imu"], {"settle_ticks": 1.5}), "settle_ticks = 1.5 should be"),
        (lambda c: SoundPlayer({"langauge": "pt"}), r"\[sound\].*'language'"),
        (lambda c: SoundPlayer({"say_command": "espeak"}), "should be a list of strings"),
    ],
)
def test_every_settings_module_refuses_a_misspelt_key_naming_the_right_one(
    build, message: str
) -> None:
    with pytest.raises(ConfigError, match=message):
        build(load_all())


def test_the_shipped_config_reads_cleanly_through_every_settings_module() -> None:
    c = load_all()
    assert BallPlaySettings.from_config(c["ballplay"]).tracker.search_tilts_deg == (0.0, 25.0)
    assert FinderSettings.from_config(c["ballplay"], "blue").color.name == "blue"
    assert ArbiterLimits.from_config(c["daemon"]["arbiter"]).queue_size == 64
    assert HeadLimits.from_config(c["head"]).speed == 3.0
    assert FallMonitor(c["imu"], c["fall"]).back_page == 11
    assert SoundPlayer(c["sound"]).say_command[-1] == "--stdin"
    assert load_settings().walk.x_mps_per_unit > 0


def test_an_unknown_walking_parameter_names_the_nearest_one() -> None:
    with pytest.raises(ValueError, match=r"'perid_time' \(nearest known: 'period_time'\)"):
        check("perid_time", 600.0)


def test_a_merge_and_each_load_are_copies_nobody_else_holds(tmp_path) -> None:
    """The shipped files are merged in place once (no copy of the whole config per file); what
    callers get must still share nothing: not with the cache, the inputs or another load."""
    from config.loader import merge, shipped

    base = {"a": {"x": 1, "seq": [1]}, "b": 2}
    over = {"a": {"y": {"z": 3}}, "b": {"c": [4]}}
    out = merge(base, over)
    assert out == {"a": {"x": 1, "seq": [1], "y": {"z": 3}}, "b": {"c": [4]}}
    out["a"]["seq"].append(2)
    out["a"]["y"]["z"] = 0
    out["b"]["c"].append(5)
    assert base == {"a": {"x": 1, "seq": [1]}, "b": 2}
    assert over == {"a": {"y": {"z": 3}}, "b": {"c": [4]}}

    user = tmp_path / "config.toml"
    user.write_text('[robot]\nname = "mine"\n')
    pristine = shipped()
    for path in (None, user):
        first = load_all(path)
        first["robot"]["name"] = "changed"
        first["zenoh"].clear()
        again = load_all(path)
        assert again["robot"]["name"] != "changed" and again["zenoh"] == pristine["zenoh"]
    assert load_all(user)["robot"] == {**pristine["robot"], "name": "mine"}
    assert shipped() == pristine


def test_a_toml_file_is_parsed_once_and_again_when_it_changes(tmp_path, monkeypatch) -> None:
    """A shipped file's parsed TOML is kept as bytecode is (under the cache prefix, unless told
    not to write): read back while the file's size and time are the same, parsed again when
    either changes or the kept copy is unreadable; never kept when marshal cannot hold it (a
    date), nor for a user's file."""
    import os
    import sys
    import tomllib

    from config import loader
    from config.loader import toml_file

    user = tmp_path / "user.toml"
    user.write_text("u = 1\n")
    monkeypatch.setattr(sys, "pycache_prefix", str(tmp_path / "cache"))
    monkeypatch.setattr(sys, "dont_write_bytecode", False)
    assert toml_file(user) == {"u": 1}
    assert not (tmp_path / "cache").exists()  # not shipped: not kept
    monkeypatch.setattr(loader, "KEPT_UNDER", (tmp_path,))
    f = tmp_path / "x.toml"
    f.write_text("a = 1\n[t]\nb = [1, 2]\n")
    assert toml_file(f) == {"a": 1, "t": {"b": [1, 2]}}
    (kept,) = (tmp_path / "cache").rglob("*.marshal")
    mine = toml_file(f)
    mine["t"]["b"].append(3)  # each call's objects are its own
    with monkeypatch.context() as m:
        m.setattr(tomllib, "loads", lambda text: pytest.fail("parsed again"))
        assert toml_file(f) == {"a": 1, "t": {"b": [1, 2]}}
    f.write_text("a = 22\n")  # another size
    assert toml_file(f) == {"a": 22}
    stamp = f.stat().st_mtime_ns
    f.write_text("a = 33\n")  # the same size at another time
    os.utime(f, ns=(stamp + 10**9, stamp + 10**9))
    assert toml_file(f) == {"a": 33}
    kept.write_bytes(b"not marshal")
    assert toml_file(f) == {"a": 33}
    dated = tmp_path / "dated.toml"
    dated.write_text("day = 1979-05-27\n")
    assert str(toml_file(dated)["day"]) == "1979-05-27"
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    other = tmp_path / "other.toml"
    other.write_text("c = 3\n")
    assert toml_file(other) == {"c": 3}
    assert [p.name for p in (tmp_path / "cache").rglob("*.marshal")] == [kept.name]
    # A motion file is text, as Path.read_text reads it: a lone CR ends a line there.
    crs = tmp_path / "crs.toml"
    crs.write_bytes(b"a = 1\rb = 2\r")
    assert toml_file(crs, universal_newlines=True) == {"a": 1, "b": 2}
    with pytest.raises(tomllib.TOMLDecodeError):
        toml_file(crs)
