"""A robot tuned with ROBOTIS's offset tuner keeps its offsets in /darwin/Data/config.ini; a
daemon whose config never imported them drives every joint off by them. The daemon says so at
start (status.bus.warnings, naming the command that imports them), and stops saying it once they
are imported; `darwin doctor` says the same."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from config.loader import load_robot
from config.robotis_offsets import NotImported, offsets_not_imported
from tests.fixtures.emulator import start_emulator_process
from tests.fixtures.system import REPO, darwin_command
from tests.integration.test_power_and_alarms import SIM, daemon
from tests.unit.test_calibrate_import import SAMPLE_INI


def _config(tmp_path: Path, ini: Path) -> Path:
    cfg = tmp_path / "config.toml"
    cfg.write_text(f'[daemon]\nrobotis_config_ini = "{ini}"\n')
    return cfg


def test_the_check_names_the_largest_offset_and_goes_quiet_once_imported(tmp_path: Path) -> None:
    ini = tmp_path / "config.ini"
    assert offsets_not_imported(ini, load_robot()) is None  # no ROBOTIS file: nothing to say
    ini.write_text(SAMPLE_INI)
    missing = offsets_not_imported(ini, load_robot())
    assert isinstance(missing, NotImported)
    assert "4 joint(s)" in missing.detail and "l_knee: +1.41°" in missing.detail
    assert f"darwin calibrate import {ini}" in missing.fix
    cfg = _config(tmp_path, ini)
    done = subprocess.run(
        darwin_command("calibrate", "import", str(ini), "--config", str(cfg)),
        capture_output=True, text=True, cwd=REPO, env={**os.environ, "DARWIN_CONFIG": ""},
    )
    assert done.returncode == 0, done.stderr
    assert offsets_not_imported(ini, load_robot(cfg)) is None
    ini.write_text("[Offset]\nID_13 = lots\n")
    broken = offsets_not_imported(ini, load_robot(cfg))
    assert broken is not None and "not a whole number" in broken.detail


def test_the_daemon_warns_at_start_about_offsets_it_does_not_have(tmp_path: Path) -> None:
    ini = tmp_path / "config.ini"
    ini.write_text(SAMPLE_INI)
    cfg = _config(tmp_path, ini)
    with (
        start_emulator_process(*SIM, link_dir=tmp_path) as sim,
        daemon(tmp_path, sim.port, "--config", str(cfg)) as robot,
    ):
        status = robot.wait_for("status", lambda s: s.state in ("running", "degraded"), 30)
        warned = [w for w in status.bus["warnings"] if str(ini) in w]
        assert len(warned) == 1 and "darwin calibrate import" in warned[0], status.bus
