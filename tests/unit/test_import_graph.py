"""The layers hold: no two packages import each other, and no two modules do at import time.

The graph is drawn from the source with ``ast`` (every ``import`` and ``from … import``,
function-local ones included, ``tests/``, ``benchmarks/``, ``scripts/`` and ``plugins/`` left
out). A package is a top-level folder's first-level subpackage, its own subpackages merged in
(``robot_daemon.bus``, ``clients.tui``), or the modules at the top of a folder (``schemas``,
``robot_daemon``). For modules, only imports run at import time count (module level).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections import defaultdict
from collections.abc import Iterable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LEFT_OUT = ("tests/", "benchmarks/", "scripts/", "plugins/")


def _modules() -> dict[str, Path]:
    listed = subprocess.run(
        ["git", "ls-files", "*.py"], capture_output=True, text=True, cwd=ROOT, check=True
    ).stdout.split()
    return {
        f[:-3].replace("/", ".").removesuffix(".__init__"): ROOT / f
        for f in listed
        if not f.startswith(LEFT_OUT)
    }


def _imported(node: ast.AST, mods: dict[str, Path]) -> list[str]:
    if isinstance(node, ast.Import):
        return [a.name for a in node.names if a.name in mods]
    if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
        subs = [f"{node.module}.{a.name}" for a in node.names]
        subs = [s for s in subs if s in mods]
        if len(subs) == len(node.names):
            return subs  # submodules of a package, not the package's __init__
        return [n for n in (node.module, *subs) if n in mods]
    return []


def _package(path: Path) -> str:
    parts = path.relative_to(ROOT).parent.parts
    return ".".join(parts[:2]) if parts else "(top)"


def _cycles(graph: dict[str, set[str]], nodes: Iterable[str]) -> list[list[str]]:
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))
    for v in list(nodes):
        if v not in index:
            visit(v)
    return found


def test_no_two_packages_import_each_other() -> None:
    mods = _modules()
    graph: dict[str, set[str]] = defaultdict(set)
    why: dict[tuple[str, str], str] = {}
    for name, path in mods.items():
        for node in ast.walk(ast.parse(path.read_text())):
            for target in _imported(node, mods):
                a, b = _package(path), _package(mods[target])
                if a != b:
                    graph[a].add(b)
                    why.setdefault((a, b), f"{name} → {target}")
    cycles = _cycles(graph, list(graph))
    edges = [why[a, b] for c in cycles for a in c for b in c if (a, b) in why]
    assert not cycles, f"packages that import each other: {cycles}; through {edges}"


def test_no_two_modules_import_each_other_at_import_time() -> None:
    mods = _modules()
    graph: dict[str, set[str]] = defaultdict(set)
    for name, path in mods.items():
        for node in ast.parse(path.read_text()).body:
            graph[name].update(t for t in _imported(node, mods) if t != name)
    assert not _cycles(graph, list(mods))
