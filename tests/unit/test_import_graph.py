"""The layers hold: every import between packages goes the way docs/architecture.md says
(:data:`ALLOWED`, the contract as data), from the client side into the daemon's only through a
public face (:data:`FACES`); no two packages import each other, and no two modules do at import
time.

The graph is drawn from the source with ``ast`` (every ``import`` and ``from … import``,
function-local ones included, and ``importlib.import_module("…")`` with a literal name;
``tests/``, ``benchmarks/``, ``scripts/`` and ``plugins/`` left out). A package is a top-level
folder's first-level subpackage, its own subpackages merged in (``robot_daemon.bus``,
``clients.tui``), or the modules at the top of a folder (``schemas``, ``robot_daemon``). For
modules, only imports run at import time count (module level).
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
    if (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Attribute | ast.Name)
        and (node.func.attr if isinstance(node.func, ast.Attribute) else node.func.id)
        in ("import_module", "__import__")
        and node.args
        and isinstance(node.args[0], ast.Constant)
    ):
        name = node.args[0].value
        return [name] if name in mods else []
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


BASE = {"schemas", "config"}
DAEMON_BASE = BASE | {"robot_daemon"}  # robot_daemon's own top modules (frames, services…)
PARTS = {"robot_daemon.bus", "robot_daemon.motion", "robot_daemon.vision"}

# The contract: each package and the packages it may import (besides itself). A package
# missing here may import nothing but BASE. docs/architecture.md (Layout) says it in words.
ALLOWED: dict[str, set[str]] = {
    "schemas": set(),
    "config": {"schemas"},
    # the daemon: launch → engine → arbiter → the parts → its top modules
    "robot_daemon": BASE,
    "robot_daemon.security": BASE,
    "robot_daemon.bus": DAEMON_BASE,
    "robot_daemon.motion": DAEMON_BASE,  # frames in, targets out: never the bus or Zenoh
    "robot_daemon.vision": DAEMON_BASE,
    "robot_daemon.arbiter": DAEMON_BASE | PARTS,
    "robot_daemon.engine": DAEMON_BASE | PARTS | {"robot_daemon.arbiter", "robot_daemon.security"},
    "robot_daemon.doctor": DAEMON_BASE | {"robot_daemon.bus"},  # the daemon through schemas
    # the simulated robot: the emulator speaks the bus's tables; the plant drives the emulator
    "robot_daemon.emulator": DAEMON_BASE | {"robot_daemon.bus"},
    "robot_daemon.plant": BASE
    | {"robot_daemon.bus", "robot_daemon.emulator", "robot_daemon.vision"},
    "robot_daemon.launch": BASE | PARTS | {
        "robot_daemon.engine", "robot_daemon.security", "robot_daemon.emulator",
        "robot_daemon.plant", "robot_daemon.doctor",
    },
    # the clients: the Robot API at the top, then what is built on it
    "clients": BASE,
    "clients.rmw": BASE,  # rmw_zenoh's wire format: a library the two below share
    "clients.ros2": BASE | {"clients", "clients.rmw"},
    "clients.recording": BASE | {"clients", "clients.rmw", "clients.learn"},
    "clients.learn": BASE | {"clients", "robot_daemon.plant", "robot_daemon.motion"},
    "clients.tui": BASE | {"clients", "clients.recording"},
    "clients.notebook": BASE | {"clients"},
    "clients.foxglove": BASE | {"clients"},
    "clients.web": BASE | {"clients"},
    "gateway": BASE | {"clients"},
}

# From the clients into the daemon's packages, only these modules: the public faces (a
# package's __init__ with __all__, or a module shared on purpose).
FACES: dict[str, set[str]] = {
    "clients.learn": {
        "robot_daemon.plant.physics",  # DirectPlant: the MuJoCo plant without an emulator
        "robot_daemon.motion.attitude",  # the policy loop's gravity estimate, as deployed
        "robot_daemon.motion.policy",  # the policy loop's settings, as deployed
    },
}


def _edges() -> list[tuple[str, str, str, str, ast.AST]]:
    """(importing package, imported package, importing module, imported module, node)."""
    mods = _modules()
    found = []
    for name, path in mods.items():
        for node in ast.walk(ast.parse(path.read_text())):
            for target in _imported(node, mods):
                a, b = _package(path), _package(mods[target])
                if a != b:
                    found.append((a, b, name, target, node))
    return found


def test_every_import_goes_the_way_the_layers_allow() -> None:
    wrong = sorted(
        f"{name} → {target}"
        for a, b, name, target, _ in _edges()
        if b not in ALLOWED.get(a, BASE)
    )
    assert not wrong, f"imports against the layers (ALLOWED): {wrong}"


def test_the_clients_reach_the_daemon_only_through_its_public_faces() -> None:
    mods = _modules()
    wrong = []
    for a, b, name, target, node in _edges():
        if not (a.split(".")[0] == "clients" and b.split(".")[0] == "robot_daemon"):
            continue
        if target not in FACES.get(a, set()):
            wrong.append(f"{name} → {target} (not a public face)")
            continue
        if mods[target].name == "__init__.py" and isinstance(node, ast.ImportFrom):
            tree = ast.parse(mods[target].read_text())
            public = {
                elt.value
                for stmt in tree.body
                if isinstance(stmt, ast.Assign)
                and any(isinstance(t, ast.Name) and t.id == "__all__" for t in stmt.targets)
                and isinstance(stmt.value, ast.List | ast.Tuple)
                for elt in stmt.value.elts
                if isinstance(elt, ast.Constant)
            }
            wrong += [f"{name} → {target}.{a_.name} (not in __all__)" for a_ in node.names
                      if a_.name not in public]
    assert not wrong, f"the clients reach into the daemon: {wrong}"


def test_the_contract_names_every_package_and_is_one_way() -> None:
    packages = {_package(p) for p in _modules().values()}
    missing = packages - {"(top)"} - set(ALLOWED)
    assert not missing, f"packages the contract misses: {missing}"
    graph = {a: set(bs) for a, bs in ALLOWED.items()}
    assert not _cycles(defaultdict(set, graph), list(graph)), "ALLOWED has a cycle"


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
