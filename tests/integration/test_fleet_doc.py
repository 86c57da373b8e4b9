"""docs/fleet.md's step-by-step block runs as written (on loopback: ROUTER is 127.0.0.1, the
ports are free ones, the password files are made first): the protected robot is listed."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

from schemas.session import free_tcp_port
from tests.fixtures.system import REPO, run_darwin, spawn_darwin, stop_group

PAGE = REPO / "docs" / "fleet.md"


def page_commands() -> list[list[str]]:
    step_by_step = PAGE.read_text().split("## A protected fleet, step by step", 1)[1]
    block = step_by_step.split("```sh", 1)[1].split("```", 1)[0]
    joined = re.sub(r"\\\n\s*", " ", block)
    return [shlex.split(line) for line in joined.splitlines()
            if line.strip() and not line.lstrip().startswith("#")]


def test_the_step_by_step_block_lists_the_protected_robot(tmp_path: Path) -> None:
    ports = {"7447": str(free_tcp_port()), "7448": str(free_tcp_port())}
    for name in ("fa", "rui"):
        (tmp_path / f"{name}.pw").write_text(f"{name}-password-123\n")

    def local(word: str) -> str:
        word = word.replace("0.0.0.0", "127.0.0.1").replace("ROUTER", "127.0.0.1")
        for port, free in ports.items():
            word = word.replace(f":{port}", f":{free}")
        return str(tmp_path / word) if word.endswith((".pw", ".toml")) else word

    running = []
    try:
        listed = None
        for argv in page_commands():
            assert argv[0] == "darwin", argv
            args = [local(a) for a in argv[1:]]
            if args[0] in ("router", "up"):
                proc = spawn_darwin(*args)
                running.append(proc)
                ready = "router: " if args[0] == "router" else "robot: "
                assert proc.stdout is not None
                for line in proc.stdout:
                    if line.startswith(ready):
                        break
                else:
                    raise AssertionError(f"darwin {args[0]} ended before {ready!r}")
            else:
                done = run_darwin(*args)
                assert done.returncode == 0, done.stderr
                listed = done.stdout
        assert listed is not None and listed.startswith("fa: "), listed
    finally:
        for proc in reversed(running):
            stop_group(proc)
            if proc.stdout is not None:
                proc.stdout.close()
