"""The gateway's limits come from config/gateway.toml, a user file or the command line, and a
value that cannot work is refused in one line naming the setting."""

from __future__ import annotations

from pathlib import Path

import pytest

from gateway.framing import BodyLimits
from gateway.settings import GatewaySettings, check_settings, load_settings
from robot_daemon.launch.cli import main
from schemas.errors import ConfigError


def test_the_shipped_limits_are_those_the_code_defaults_to(tmp_path: Path) -> None:
    empty = tmp_path / "empty.toml"  # so no user file on this machine counts
    empty.write_text("")
    shipped = load_settings(empty)
    assert shipped == GatewaySettings()
    assert shipped.body_limits == BodyLimits()
    assert shipped.max_incoming == shipped.max_partial_frame < shipped.max_message


def test_a_user_file_sets_the_limits(tmp_path: Path) -> None:
    path = tmp_path / "gw.toml"
    path.write_text(
        "[gateway]\nmax_connections = 3\nidle_timeout = 2\nmax_partial_frame = 2000000\n"
        "max_depth = 5\nmax_number_length = 9\n"
    )
    s = load_settings(path)
    assert (s.max_connections, s.idle_timeout) == (3, 2.0)
    assert s.body_limits == BodyLimits(5, 9)
    assert s.max_incoming == s.max_message  # the smaller of the two bounds what comes in


@pytest.mark.parametrize(
    ("name", "value", "needle"),
    [
        ("max_connections", 0, "at least 1"),
        ("idle_timeout", -1.0, "at least 0"),
        ("lease_idle_timeout", -5.0, "at least 0"),
        ("max_partial_frame", 0, "at least 1"),
        ("max_depth", 0, "within 1..256"),
        ("max_depth", 1000, "within 1..256"),  # json would hit Python's recursion limit first
        ("max_number_length", 5000, "within 1..4300"),  # int() refuses longer literals
    ],
)
def test_unusable_limits_are_refused_naming_the_setting(
    name: str, value: float, needle: str
) -> None:
    with pytest.raises(ConfigError, match=rf"\[gateway\] {name} must be {needle}"):
        check_settings(GatewaySettings().with_overrides(**{name: value}))


def test_the_command_line_is_checked_too(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["gateway", "--max-number-length", "9999", "--connect", "tcp/127.0.0.1:1"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["darwin gateway: [gateway] max_number_length must be within 1..4300, not 9999"]
