"""The child's side of :mod:`robot_daemon.launch.children`: what every ``darwin`` program does at
its start in case ``darwin up`` or ``darwin daemon --sim`` started it — end with that parent, and
wait to be let go when started held. Apart from the parent's side so that a program that starts
no child loads neither ``subprocess`` nor ``ctypes`` for it."""

from __future__ import annotations

import os
import signal
import threading

PARENT_FD_ENV = "DARWIN_PARENT_FD"
GO_FD_ENV = "DARWIN_GO_FD"


def watch_parent() -> None:
    """In a child started by a :class:`~robot_daemon.launch.children.Child`: SIGTERM ourselves
    when the parent's pipe closes (the parent died), the fallback where ``PR_SET_PDEATHSIG``
    does not exist."""
    fd_text = os.environ.pop(PARENT_FD_ENV, "")
    if not fd_text.isdigit():
        return
    fd = int(fd_text)

    def watch() -> None:
        try:
            while os.read(fd, 1):
                pass
        except OSError:
            pass
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def wait_for_go() -> bool:
    """In a child started held: wait until the parent says go (True), or lets go of the pipe
    without saying it (False: it will not run). Not held: True at once."""
    fd_text = os.environ.pop(GO_FD_ENV, "")
    if not fd_text.isdigit():
        return True
    fd = int(fd_text)
    try:
        return os.read(fd, 1) == b"1"
    except OSError:
        return False
    finally:
        os.close(fd)
