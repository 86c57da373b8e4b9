"""docs/robot.md's recipe as scripts/i386-check reads it (the check itself needs root and the
network and runs from scripts/test): one install block, one daemon command, and the apt packages
the robot's Python takes instead of wheels PyPI does not have for 32-bit Linux."""

from __future__ import annotations

import importlib.util
import os
import shlex
import sys
import threading
import tomllib
from pathlib import Path
from types import ModuleType

import pytest

from robot_daemon.engine.telemetry_rate import check_rate

REPO = Path(__file__).resolve().parents[2]


def load_check() -> ModuleType:
    spec = importlib.util.spec_from_file_location("i386_check", REPO / "scripts" / "i386_check.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["i386_check"] = module
    spec.loader.exec_module(module)
    return module


def test_the_recipe_installs_the_daemon_first_and_has_one_daemon_command() -> None:
    check = load_check()
    blocks, command = check.recipe()
    packages = check.apt_packages(blocks)
    install = blocks[0]
    for needed in ("python3-venv", "python3-numpy", "python3-opencv", "python3-serial",
                   "python3-msgpack"):
        assert needed in packages
    assert "python3 -m venv --system-site-packages /opt/darwin" in install
    assert "/opt/darwin/bin/pip install ~/darwin-zenoh" in install
    words = shlex.split(command)
    assert words[:2] == ["/opt/darwin/bin/darwin", "daemon"]
    assert check.ROBOT_PORT in words and check.ROBOT_LISTEN in words


def test_fenced_blocks_are_found_by_their_info_string_only() -> None:
    check = load_check()
    text = ("```sh\nnot me\n```\n```{.sh .recipe}\necho a\necho b\n```\n"
            "```{.sh .recipe-x}\nno\n```\n")
    assert check.fenced_blocks(text, check.RECIPE) == ["echo a\necho b\n"]


def test_the_core_requirements_are_the_ones_the_check_dry_runs() -> None:
    check = load_check()
    reqs = check.core_requirements()
    assert any(r.startswith("eclipse-zenoh") for r in reqs)
    assert any(r.startswith("numpy>=1.24") for r in reqs)


def test_opencv_comes_after_the_daemon_and_blocks_are_named_by_their_comment() -> None:
    check = load_check()
    blocks, _ = check.recipe()
    assert "python3-opencv" not in blocks[0]
    names = [check.label(b) for b in blocks]
    assert names == [
        "the daemon",
        "the compiled hot path, optional",
        "OpenCV, for the camera and ball play",
        "the loop's settings for the Atom",
    ]


def test_the_atom_settings_are_settings_the_daemon_knows() -> None:
    """The config the recipe writes (and the robot-run command reads) names only settings of
    the shipped [daemon] table, with values the daemon takes."""
    check = load_check()
    blocks, command = check.recipe()
    block = blocks[-1]
    body = block.split("<<'EOF'\n", 1)[1].split("\nEOF", 1)[0]
    path = shlex.split(block.split("cat > ", 1)[1])[0]
    assert f"--config {path}" in command
    written = tomllib.loads(body)["daemon"]
    shipped = tomllib.loads((REPO / "config" / "daemon.toml").read_text())["daemon"]
    assert set(written) <= set(shipped)
    assert check_rate(written["telemetry_hz"], "daemon.telemetry_hz") > 0
    assert 0 < written["servo_reads_per_tick"] < 20


@pytest.mark.skipif(os.geteuid() != 0, reason="giving a process its priority back needs root")
def test_the_recipe_yields_while_the_suite_runs_and_takes_its_share_when_it_ends(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    check = load_check()
    marker = tmp_path / "beside"
    marker.touch()
    monkeypatch.setenv(check.BESIDE_ENV, str(marker))
    go = tmp_path / "go"
    os.mkfifo(go)
    a, b, c = (tmp_path / n for n in "abc")
    # The recipe's shell: its niceness, then (told the suite ended) it waits to be given its
    # priority back, and a process it starts after that has it too.
    script = (f'nice > {a}; read line < {go}; '
              f'while [ "$(nice)" != 0 ]; do sleep 0.05; done; nice > {b}; sh -c nice > {c}')
    log = tmp_path / "log.txt"
    failed: list[BaseException] = []

    def recipe() -> None:
        try:
            check.run_recipe(["bash", "-c", script], "the test recipe", log)
        except BaseException as exc:  # reported by the test below
            failed.append(exc)

    runner = threading.Thread(target=recipe, daemon=True)
    runner.start()
    try:
        with go.open("w") as say:  # opens once the shell has written its niceness and reads
            assert a.read_text().split() == [str(check.RECIPE_NICE)]
            marker.unlink()  # the suite ended
            say.write("go\n")
    finally:
        marker.unlink(missing_ok=True)  # whatever failed above, the recipe ends
    runner.join(timeout=60)
    assert not runner.is_alive() and not failed, failed
    assert b.read_text().split() == ["0"] and c.read_text().split() == ["0"]


def test_the_recipe_alone_runs_at_normal_priority(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    check = load_check()
    monkeypatch.delenv(check.BESIDE_ENV, raising=False)
    out = tmp_path / "nice"
    check.run_recipe(["bash", "-c", f"nice > {out}"], "the test recipe", tmp_path / "log.txt")
    assert out.read_text().split() == ["0"]
    with pytest.raises(check.CheckFailed, match="the test recipe failed"):
        check.run_recipe(["false"], "the test recipe", tmp_path / "log.txt")
