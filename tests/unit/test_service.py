"""`darwin service`: the systemd units pass `systemd-analyze verify`, the udev rule says what the
CM-730 needs, install → status → remove round-trips in a temp root, and a machine without
systemd gets one line."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from robot_daemon.launch import cli
from robot_daemon.launch import service as svc
from tests.fixtures.system import run_darwin


def _install(root: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    config = root.parent / "user.toml"
    config.write_text("[daemon]\ntick_ms = 8.0\n")
    return run_darwin("service", "install", "--root", str(root), "--config", str(config), *extra)


def test_install_status_remove_round_trip(tmp_path: Path) -> None:
    root = tmp_path / "root"
    done = _install(root, "--gateway")
    assert done.returncode == 0, done.stderr
    written = [line.removeprefix("file: ") for line in done.stdout.splitlines()]
    units = root / svc.UNIT_DIR
    assert str(units / "darwin-daemon.service") in written
    assert str(units / "darwin-gateway.service") in written
    assert str(root / svc.UDEV_DIR / svc.UDEV_RULE) in written
    daemon_unit = (units / "darwin-daemon.service").read_text()
    assert f"--config {tmp_path / 'user.toml'}" in daemon_unit  # the user's config baked in
    assert f"--port /dev/{svc.DEVICE_NAME}" in daemon_unit
    assert "Restart=on-failure" in daemon_unit and "StandardOutput=journal" in daemon_unit
    assert (units / "brltty-udev.service").readlink() == Path("/dev/null")

    status = run_darwin("service", "status", "--root", str(root))
    assert status.returncode == 0, status.stderr
    lines = status.stdout.splitlines()
    assert lines[0].startswith("darwin-daemon.service: installed")
    assert lines[1].startswith("darwin-gateway.service: installed")
    assert lines[2] == "darwin-router.service: not installed"
    assert lines[3].startswith("udev rule: installed")

    removed = run_darwin("service", "remove", "--root", str(root))
    assert removed.returncode == 0, removed.stderr
    assert sorted(p.name for p in units.iterdir()) == []
    assert not (root / svc.UDEV_DIR / svc.UDEV_RULE).exists()
    after = run_darwin("service", "status", "--root", str(root))
    assert "darwin-daemon.service: not installed" in after.stdout


def test_dry_run_writes_nothing(tmp_path: Path) -> None:
    done = _install(tmp_path / "root", "--dry-run")
    assert done.returncode == 0, done.stderr
    assert "ExecStart=" in done.stdout
    assert not (tmp_path / "root").exists()


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="apt-get install systemd")
def test_units_pass_systemd_analyze_verify(tmp_path: Path) -> None:
    root = tmp_path / "root"
    assert _install(root, "--gateway", "--router").returncode == 0
    units = sorted((root / svc.UNIT_DIR).glob("darwin-*.service"))
    assert len(units) == 3

    def verify(*paths: Path) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            ["systemd-analyze", "verify", *map(str, paths)],
            capture_output=True,
            text=True,
            timeout=120,
            cwd=units[0].parent,
        )

    done = verify(*units)
    # verify exits 0 on a value it ignores, but says so: no output at all is the pass.
    assert (done.returncode, done.stdout + done.stderr) == (0, "")
    # It is sensitive: a value systemd cannot parse is reported.
    bad = units[0].parent / "darwin-bad.service"
    bad.write_text(units[0].read_text().replace("TimeoutStopSec=", "TimeoutStopSec=x"))
    assert "Failed to parse" in verify(bad).stderr


def test_udev_rule_names_the_cm730_sets_the_latency_and_keeps_modemmanager_off() -> None:
    rules = svc.rule_fields(svc.udev_rule())
    for rule in rules:
        assert rule["SUBSYSTEM"] == ("==", "tty")
        assert rule["ATTRS{idVendor}"] == ("==", "0403")
        assert rule["ATTRS{idProduct}"] == ("==", "6001")
    merged = {k: v for rule in rules for k, v in rule.items()}
    assert merged["SYMLINK"] == ("+=", svc.DEVICE_NAME)
    assert merged["ENV{ID_MM_DEVICE_IGNORE}"] == ("=", "1")
    assert merged["ATTR{device/latency_timer}"] == ("=", "1")
    if shutil.which("udevadm"):
        # udevadm verify (systemd ≥ 254) checks the syntax as udev itself reads it.
        path = Path("/tmp") / f"darwin-test-{svc.UDEV_RULE}"
        path.write_text(svc.udev_rule())
        try:
            done = subprocess.run(
                ["udevadm", "verify", str(path)], capture_output=True, text=True, timeout=60
            )
            if "Unknown command" not in done.stderr:
                assert done.returncode == 0, done.stderr
        finally:
            path.unlink()


def test_a_rule_that_udev_would_not_read_is_refused_by_the_parser() -> None:
    with pytest.raises(ValueError, match="double quotes"):
        svc.rule_fields('SUBSYSTEM=="tty", SYMLINK+=darwin')


def test_without_systemd_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # systemd's own marker (sd_booted) is the edge of the world here: point it at nothing.
    monkeypatch.setattr(svc, "SYSTEMD_RUNNING", tmp_path / "absent")
    assert cli.main(["service", "status"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.startswith("darwin service: systemd is not running on this machine")


def test_the_commands_docs_service_md_shows(tmp_path: Path) -> None:
    doc = (Path(__file__).resolve().parents[2] / "docs" / "service.md").read_text()
    block = doc.split("```sh\n", 1)[1].split("```", 1)[0]
    commands = [line.split() for line in block.splitlines() if line.strip()]
    assert len(commands) == 4
    config = tmp_path / "config.toml"
    config.write_text("")
    root = tmp_path / "root"
    outputs = []
    for argv in commands:
        argv = argv[1:] if argv[0] == "sudo" else argv
        assert argv[0] == "/opt/darwin/bin/darwin"  # where docs/robot.md's recipe installs it
        argv = [str(config) if a == "/etc/darwin/config.toml" else a for a in argv[1:]]
        done = run_darwin(*argv, "--root", str(root))
        assert done.returncode == 0, done.stderr
        outputs.append(done.stdout)
    assert "darwin-router.service: installed" in outputs[2]
    assert not list((root / svc.UNIT_DIR).iterdir())
