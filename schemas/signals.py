"""Stopping a program on SIGINT and SIGTERM from a thread of its own.

Python runs a signal handler on the main thread between two bytecodes, wherever that thread
is. Inside ``threading.Event.wait`` it may be holding the event's own lock, and an
``Event.set`` in the handler then waits for that lock forever: ``darwin replay`` hung so on
3 of 300 SIGTERMs (its main thread waits on the event its handler set), and every program
whose handler set an event it also waited on could (the daemon's sets the wake event its
motion loop waits on). The handler here takes no lock: it writes the signal's number to a
pipe, and a thread reading the pipe runs the callback, where locks are safe.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Callable, Iterable
from types import FrameType

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)

# One pipe and one relay thread per process, made at the first call; a later call replaces the
# callback, as a later signal.signal replaces a handler.
_callback: Callable[[int], None] | None = None
_write_fd: int | None = None
_lock = threading.Lock()


def on_stop_signals(
    callback: Callable[[int], None], signals: Iterable[int] = STOP_SIGNALS
) -> None:
    """From now on each of ``signals`` calls ``callback(signum)`` on a thread named
    ``stop-signals`` (the handler only hands it over). Call it from the main thread."""
    global _callback, _write_fd
    with _lock:
        _callback = callback
        if _write_fd is None:
            read_fd, _write_fd = os.pipe()
            # Never wait in a handler: a full pipe already holds a stop.
            os.set_blocking(_write_fd, False)
            relay = threading.Thread(target=_relay, args=(read_fd,), name="stop-signals")
            relay.daemon = True
            relay.start()
    for sig in signals:
        signal.signal(sig, _handler)


def _handler(signum: int, _frame: FrameType | None) -> None:
    if _write_fd is not None:
        with contextlib.suppress(OSError):
            os.write(_write_fd, bytes((signum,)))


def _relay(read_fd: int) -> None:
    while data := os.read(read_fd, 64):
        for signum in data:
            callback = _callback
            if callback is not None:
                callback(signum)
