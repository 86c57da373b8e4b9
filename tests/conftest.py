"""Shared fixtures live in tests/fixtures/ (one plugin module per part of the system).

A run leaves nothing behind (tests/fixtures/leftovers.py): its first pytest process makes a run
directory for every temporary file and a watchdog that ends whatever the run started, however
pytest ends. Under pytest-xdist (``scripts/test`` runs ``-n auto``) the workers share that
directory and the mark; ports come from ``schemas.session.free_tcp_port``, robot names, temp
dirs, ptys and namespace names are unique per test, so workers never meet.
"""

from __future__ import annotations

import os
import sys
import tempfile

import pytest

from tests.fixtures import leftovers

pytest_plugins = [
    "tests.fixtures.emulator",
    "tests.fixtures.system",
    "tests.fixtures.zenoh_pair",
]

_OWNER_ENV = "DARWIN_TEST_RUN_OWNER"


def _is_worker() -> bool:
    # An xdist worker is a child of the run's first pytest; a pytest a test starts is not.
    return "PYTEST_XDIST_WORKER" in os.environ and str(os.getppid()) == os.environ.get(_OWNER_ENV)


_WATCHDOG: leftovers.Watchdog | None = None
if not _is_worker():
    _WATCHDOG = leftovers.Watchdog()
    os.environ[_OWNER_ENV] = str(os.getpid())

# Daemons started by the tests (in-process or `darwin up`) read the user's own action pages
# from here, never from the developer's ~/.config/darwin/motions; a test that saves pages
# points DARWIN_MOTIONS (or [motion] user_library) at a folder of its own. One per process
# (each xdist worker too), in the run directory, so it goes with the run.
os.environ["DARWIN_MOTIONS"] = tempfile.mkdtemp(prefix="motions-")


def pytest_configure(config: pytest.Config) -> None:
    if _WATCHDOG is not None and config.option.basetemp is None:
        # pytest's tmp_path too (xdist gives each worker a folder of it).
        config.option.basetemp = str(_WATCHDOG.root / "pytest")


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config: pytest.Config) -> None:
    if _WATCHDOG is None:
        return
    stopped = _WATCHDOG.finish()
    if stopped:
        print(
            "\nleft behind by the tests and stopped now (a fixture that does not clean up):\n  "
            + "\n  ".join(stopped),
            file=sys.stderr,
        )
    if _WATCHDOG.keep:
        print(f"\nDARWIN_KEEP_TMP=1: the run's files are in {_WATCHDOG.root}", file=sys.stderr)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    # The long tier runs when -m says so (`-m long`, CI's second command); the default run
    # keeps the short form of each.
    if not config.option.markexpr:
        long = [item for item in items if item.get_closest_marker("long")]
        if long:
            config.hook.pytest_deselected(items=long)
            items[:] = [item for item in items if not item.get_closest_marker("long")]
    # The tests of the shared robot first, one after another, so that it runs only while they
    # do (tests/fixtures/system.py, SharedSystem): pytest-xdist hands each worker a run of
    # consecutive tests and takes work back from the end, so they stay on one worker. Then
    # the slowest: with -n, a worker that starts a minutes-long test last would run alone at
    # the end while the others wait.
    items.sort(
        key=lambda item: (
            "robot_system" not in getattr(item, "fixturenames", ()),
            item.get_closest_marker("slow") is None,
        )
    )
