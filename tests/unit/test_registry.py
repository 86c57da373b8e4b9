"""The `darwin` commands and `darwin up`'s adapters come from the packages that bring them
(schemas/registry.py), and the robot's package names none of the others."""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

from robot_daemon.launch import up
from robot_daemon.launch.cli import COMMANDS
from schemas import registry

REPO = Path(__file__).resolve().parents[2]


def test_the_built_in_providers_are_the_declared_entry_points() -> None:
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    declared = project["entry-points"][registry.GROUP]
    assert tuple(declared.values()) == registry.BUILT_IN


def test_every_command_and_adapter_is_registered_once() -> None:
    names = [c.name for c in registry.commands()]
    assert len(names) == len(set(names)) == len(COMMANDS)
    assert {"up", "daemon", "gateway", "tui", "ros2", "foxglove", "web"} <= set(COMMANDS)
    for adapter in registry.adapters():
        assert adapter.name in COMMANDS, f"adapter {adapter.name} has no command"
    assert [a.name for a in registry.adapters() if a.ui] == ["tui"]


def test_up_offers_each_adapter() -> None:
    import argparse

    parser = argparse.ArgumentParser()
    up.add_arguments(parser)
    args = parser.parse_args(["--no-gateway", "--ros2", "--web-listen", "127.0.0.1:0"])
    wanted = {a.name: up.wanted(args, a) for a in registry.adapters()}
    assert wanted == {"gateway": False, "ros2": True, "foxglove": False, "web": False, "tui": False}


def test_the_robot_package_imports_no_adapter() -> None:
    """Nothing under robot_daemon/ imports the gateway or a client (the doctor reads a running
    daemon through the key space: robot_daemon/doctor/daemon_link.py)."""
    found = []
    for path in sorted((REPO / "robot_daemon").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            found += [
                (str(path.relative_to(REPO)), n)
                for n in names
                if n.split(".")[0] in {"gateway", "clients"}
            ]
    assert found == []
