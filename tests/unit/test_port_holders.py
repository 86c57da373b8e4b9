"""The watch for a second program on the serial port (robot_daemon/bus/preflight.py,
HolderWatch): a real pty, real processes opening and closing it."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterator

import pytest

from robot_daemon.bus.preflight import HolderWatch, OpenWatch

OPENER = (
    "import os, sys; fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY); "
    "print('open', flush=True); sys.stdin.read()"
)


@pytest.fixture
def pty_port() -> Iterator[str]:
    """A pty's device; this test keeps only the master, as the emulator does."""
    master, slave = os.openpty()
    path = os.ttyname(slave)
    os.close(slave)
    yield path
    os.close(master)


def opener(path: str) -> subprocess.Popen[str]:
    """A process that opens ``path`` and keeps it open until its stdin closes."""
    proc = subprocess.Popen(
        [sys.executable, "-c", OPENER, path],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None and proc.stdout.readline() == "open\n"
    return proc


def close(proc: subprocess.Popen[str]) -> None:
    assert proc.stdin is not None and proc.stdout is not None
    proc.stdin.close()
    proc.wait(timeout=30)
    proc.stdout.close()


def until(watch: HolderWatch, seen: Callable[[], bool], timeout: float = 30.0) -> None:
    """Each look at the holders in turn until ``seen()``."""
    deadline = time.monotonic() + timeout
    n = watch.walks
    while not seen():
        n += 1
        left = max(0.0, deadline - time.monotonic())
        assert watch.wait_walks(n, left), f"no look at the holders within {timeout} s"


def holds(watch: HolderWatch, proc: subprocess.Popen[str]) -> bool:
    return any(pid == proc.pid for pid, _ in watch.current)


def test_the_kernels_word_of_an_open_and_a_close_makes_the_watch_look(pty_port: str) -> None:
    path = pty_port
    # An hour between looks by the clock: only the kernel's word can make this one look.
    watch = HolderWatch(path, interval=3600.0)
    try:
        assert watch.by_event and watch.walks == 0
        proc = opener(path)
        try:
            until(watch, lambda: holds(watch, proc))
            assert [pid for pid, _ in watch.new()] == [proc.pid]
            assert watch.new() == []  # handed over once
        finally:
            close(proc)
        until(watch, lambda: not watch.current)
    finally:
        watch.close()


def test_without_inotify_the_clock_makes_it_look(
    pty_port: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(OpenWatch, "create", classmethod(lambda cls, path: None))
    watch = HolderWatch(pty_port, interval=0.05)
    try:
        assert not watch.by_event
        proc = opener(pty_port)
        try:
            until(watch, lambda: holds(watch, proc))
            assert [pid for pid, _ in watch.new()] == [proc.pid]
        finally:
            close(proc)
        until(watch, lambda: not watch.current)
    finally:
        watch.close()


def test_a_file_inotify_cannot_watch_is_watched_by_the_clock(tmp_path) -> None:
    assert OpenWatch.create(str(tmp_path / "no such port")) is None
