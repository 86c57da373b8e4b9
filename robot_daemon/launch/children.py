"""Child processes of ``darwin up`` and ``darwin daemon --sim``: start a ``darwin`` subcommand,
wait for the line that says where it listens, relay the rest, stop it cleanly.

A child may be started *held* (``Child(held=True)``): it imports its program and parses its
options, then waits on a pipe from the parent (``DARWIN_GO_FD``) until :meth:`Child.go`, so its
start-up overlaps whatever the parent waits for first (``darwin up``'s adapters, the daemon).

A child never outlives its parent, however the parent ends (SIGKILL included): on Linux the
kernel sends it SIGTERM when the parent dies (``PR_SET_PDEATHSIG``), and everywhere it watches a
pipe from the parent (``DARWIN_PARENT_FD``) whose end-of-file means the same. SIGTERM is the
child's ordinary clean stop, so a daemon orphaned this way still halts the robot first. The
child's side of both pipes is :mod:`robot_daemon.launch.child_side`.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping
from typing import IO

from robot_daemon.launch.child_side import GO_FD_ENV, PARENT_FD_ENV
from schemas.errors import DarwinError

_PR_SET_PDEATHSIG = 1


def _prctl() -> Callable[..., int] | None:
    if not sys.platform.startswith("linux"):
        return None
    try:
        # The program's own symbols include the C library's: no need to look for libc by name
        # (ctypes.util.find_library runs `ldconfig -p` in a subprocess, in every process).
        return ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None


_PRCTL = _prctl()  # looked up here: the child between fork and exec only calls it


def _die_with(parent: int, own_group: bool = False) -> Callable[[], None]:
    def preexec() -> None:
        if own_group:
            os.setpgid(0, 0)
        if _PRCTL is not None:
            _PRCTL(_PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != parent:  # the parent died before the line above took effect
            os.kill(os.getpid(), signal.SIGTERM)

    return preexec


class ChildError(DarwinError):
    """A child program exited, or never printed its address; the message says which."""


class Child:
    """A ``darwin <command>`` child whose stdout lines are read by a thread."""

    def __init__(
        self,
        name: str,
        args: list[str],
        relay: Callable[[str, str], None] | None = None,
        ready: bool = False,
        own_group: bool = False,
        env: Mapping[str, str] | None = None,
        held: bool = False,
    ) -> None:
        """``ready=True``: relay every line at once (nobody waits for an address line).
        ``own_group=True``: out of the terminal's process group, so Ctrl-C reaches only the
        parent, which stops this child when it is done with it (still dying with the parent).
        ``env``: its environment (default this process's). ``held=True``: it loads and then
        waits for :meth:`go` before it runs."""
        self.name = name
        self.args = args
        self.env = env
        self._relay = relay
        self._lines: queue.Queue[str | None] = queue.Queue()
        self._ready = ready
        self.output: list[str] = []
        self.errors: list[str] = []  # its stderr, relayed once ready, kept for failures
        self._held_errors: list[str] = []
        self._ready_lock = threading.Lock()
        watch_r, self._watch_w = os.pipe()  # our end stays open until we die
        passed = {PARENT_FD_ENV: watch_r}
        self._go_w = -1
        if held:
            passed[GO_FD_ENV], self._go_w = os.pipe()
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "robot_daemon.launch.cli", *args],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                stdin=subprocess.DEVNULL,
                text=True,
                env=dict(
                    os.environ if env is None else env,
                    PYTHONUNBUFFERED="1",
                    **{k: str(fd) for k, fd in passed.items()},
                ),
                pass_fds=tuple(passed.values()),
                preexec_fn=_die_with(os.getpid(), own_group),
            )
        finally:
            for fd in passed.values():
                os.close(fd)
        self._reader = threading.Thread(target=self._read, name=f"{name}-out", daemon=True)
        self._reader.start()
        self._err_reader = threading.Thread(target=self._read_err, name=f"{name}-err", daemon=True)
        self._err_reader.start()

    def _read_err(self) -> None:
        assert self.proc.stderr is not None
        self._pump(self.proc.stderr, self.errors, self._held_errors.append)

    def _pump(self, stream: IO[str], kept: list[str], before_ready: Callable[[str], None]) -> None:
        """Each line of ``stream`` kept, and relayed once the child is ready; before that it
        goes to ``before_ready`` (``wait_line`` hands it on when readiness comes)."""
        for line in stream:
            line = line.rstrip("\n")
            kept.append(line)
            with self._ready_lock:
                held = not self._ready
                if held:
                    before_ready(line)
            if not held and self._relay is not None:
                self._relay(self.name, line)

    def failure(self) -> str:
        """The child's own one-line account of why it stopped (``darwin X: …``), if it gave
        one, else everything it said."""
        self._err_reader.join(timeout=2.0)
        prefix = f"darwin {self.args[0]}: " if self.args else "darwin "
        mine = [line for line in self.errors if line.startswith(prefix)]
        if mine:
            return mine[-1][len(prefix) :]
        said = [*self.output, *self.errors]
        return "its output:\n" + "\n".join(said) if said else "it said nothing"

    def _read(self) -> None:
        assert self.proc.stdout is not None
        self._pump(self.proc.stdout, self.output, self._lines.put)
        self._lines.put(None)

    def wait_line(self, prefix: str, timeout: float) -> str:
        """The rest of the first line starting with ``prefix``; raises ``ChildError`` if the
        child exits or stays silent."""
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                self.stop()
                raise ChildError(
                    f"`darwin {' '.join(self.args)}` did not say {prefix!r} within "
                    f"{timeout:.0f} s; {self.failure()}"
                )
            try:
                line = self._lines.get(timeout=remaining)
            except queue.Empty:
                continue
            if line is None:
                code = self.proc.wait()
                raise ChildError(f"{self.name} exited with {code}: {self.failure()}")
            if line.startswith(prefix):
                with self._ready_lock:
                    self._ready = True
                    held, self._held_errors = self._held_errors, []
                if self._relay is not None:
                    for err in held:
                        self._relay(self.name, err)
                # Lines that arrived before readiness are relayed now, in order.
                while True:
                    try:
                        rest = self._lines.get_nowait()
                    except queue.Empty:
                        break
                    if rest is not None and self._relay is not None:
                        self._relay(self.name, rest)
                return line[len(prefix) :].strip()
            if self._relay is not None:
                self._relay(self.name, line)

    def go(self) -> None:
        """Let a child started held run (nothing for one that was not)."""
        if self._go_w >= 0:
            with contextlib.suppress(OSError):  # it died meanwhile: wait_line says so
                os.write(self._go_w, b"1")
            os.close(self._go_w)
            self._go_w = -1

    def running(self) -> bool:
        return self.proc.poll() is None

    def stop(self, timeout: float = 5.0) -> int | None:
        """SIGTERM, then SIGKILL after ``timeout``; returns the exit code."""
        if self._go_w >= 0:  # held and never let go: it ends without running
            os.close(self._go_w)
            self._go_w = -1
        if self._watch_w >= 0:
            os.close(self._watch_w)
            self._watch_w = -1
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    self.proc.kill()
                self.proc.wait(timeout=5)
        return self.proc.returncode


def relay_to_stderr(name: str, line: str) -> None:
    print(f"[{name}] {line}", file=sys.stderr, flush=True)
