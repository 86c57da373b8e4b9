"""Child processes of ``darwin up`` and ``darwin daemon --sim``: start a ``darwin`` subcommand,
wait for the line that says where it listens, relay the rest, stop it cleanly."""

from __future__ import annotations

import contextlib
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable

from schemas.errors import DarwinError


class ChildError(DarwinError):
    pass


class Child:
    """A ``darwin <command>`` child whose stdout lines are read by a thread."""

    def __init__(
        self, name: str, args: list[str], relay: Callable[[str, str], None] | None = None
    ) -> None:
        self.name = name
        self.args = args
        self._relay = relay
        self._lines: queue.Queue[str | None] = queue.Queue()
        self._ready = False
        self.output: list[str] = []
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "robot_daemon.cli", *args],
            stdout=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
            text=True,
            env=dict(os.environ, PYTHONUNBUFFERED="1"),
        )
        self._reader = threading.Thread(target=self._read, name=f"{name}-out", daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            line = line.rstrip("\n")
            self.output.append(line)
            if self._ready:
                if self._relay is not None:
                    self._relay(self.name, line)
            else:
                self._lines.put(line)
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
                    f"{timeout:.0f} s; its output:\n" + "\n".join(self.output)
                )
            try:
                line = self._lines.get(timeout=remaining)
            except queue.Empty:
                continue
            if line is None:
                code = self.proc.wait()
                raise ChildError(
                    f"`darwin {' '.join(self.args)}` exited with {code} before it was ready"
                    + ("; its output:\n" + "\n".join(self.output) if self.output else "")
                )
            if line.startswith(prefix):
                self._ready = True
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

    def running(self) -> bool:
        return self.proc.poll() is None

    def stop(self, timeout: float = 5.0) -> int | None:
        """SIGTERM, then SIGKILL after ``timeout``; returns the exit code."""
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
