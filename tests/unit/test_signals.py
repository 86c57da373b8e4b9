"""A stop signal ends a program's wait wherever its main thread is (schemas/signals.py): also
when it comes in while the main thread holds the lock of the very event the stop sets, where
an ``Event.set`` in the handler deadlocked (``darwin replay`` hung on 3 of 300 SIGTERMs). The
program runs in a process of its own: a deadlock there is a failure here, not a hung suite."""

from __future__ import annotations

import subprocess
import sys
import textwrap

from tests.fixtures.system import REPO

PROGRAM = textwrap.dedent(
    """
    import os, signal, threading
    from schemas.signals import on_stop_signals

    stop = threading.Event()
    heard = []
    on_stop_signals(lambda signum: (heard.append(signum), stop.set()))
    handler = signal.getsignal(signal.SIGTERM)
    handled = threading.Event()

    def noted(signum, frame):
        handler(signum, frame)
        handled.set()

    signal.signal(signal.SIGTERM, noted)
    with stop._cond:  # where Event.wait holds it
        os.kill(os.getpid(), signal.SIGTERM)
        # The handler runs on this thread at its next bytecode, the lock held: one that
        # took the lock would never return from here.
        while not handled.is_set():
            pass
    print("stopped by", heard if stop.wait(30) else "nothing", flush=True)
    """
)


def test_a_signal_that_comes_while_the_main_thread_holds_the_events_lock_still_stops_it() -> None:
    try:
        done = subprocess.run(
            [sys.executable, "-c", PROGRAM], cwd=REPO, capture_output=True, text=True, timeout=60
        )
    except subprocess.TimeoutExpired as exc:
        raise AssertionError("the program deadlocked in its signal handler") from exc
    assert done.stdout.strip() == "stopped by [15]", done.stderr
