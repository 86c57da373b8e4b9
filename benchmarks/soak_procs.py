"""The processes of ``benchmarks/soak.py``: started (in a network namespace or not) in their own
process group, their output read by a thread, killed and started again, measured from /proc."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("DARWIN_")}
    env.update(PYTHONUNBUFFERED="1", DARWIN_CLIENT_CONFIG=os.devnull,
               PYTHONPATH=str(REPO))
    return env


class Proc:
    def __init__(self, name: str, cmd: list[str], ready: str, net: Any, ns: str | None):
        self.name, self.cmd, self.ready, self.net, self.ns = name, cmd, ready, net, ns
        self.proc: subprocess.Popen[str] | None = None
        self.lines: deque[str] = deque(maxlen=400)
        self.json: deque[dict[str, Any]] = deque(maxlen=400)
        self.cond = threading.Condition()
        self.ready_rest = ""
        self._ready = False

    def start(self) -> None:
        kwargs: dict[str, Any] = dict(stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                      cwd=REPO, env=_env())
        if self.net is not None and self.ns is not None:
            self.proc = self.net.popen(self.ns, self.cmd, **kwargs)
        else:
            self.proc = subprocess.Popen(self.cmd, start_new_session=True, **kwargs)
        self._ready = not self.ready  # nothing to wait for (the recorder prints nothing)
        threading.Thread(target=self._read, args=(self.proc,), daemon=True).start()

    def _read(self, proc: subprocess.Popen[str]) -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            line = line.rstrip("\n")
            with self.cond:
                self.lines.append(line)
                if line.startswith("{"):
                    with contextlib.suppress(ValueError):
                        self.json.append(json.loads(line))
                if not self._ready and line.startswith(self.ready):
                    self._ready, self.ready_rest = True, line[len(self.ready):]
                self.cond.notify_all()
        with self.cond:
            self.cond.notify_all()

    def wait_ready(self, timeout: float) -> bool:
        with self.cond:
            return self.cond.wait_for(lambda: self._ready or not self.running(), timeout) and (
                self._ready)

    def last_json(self, key: str) -> dict[str, Any] | None:
        with self.cond:
            return next((m for m in reversed(self.json) if key in m), None)

    def wait_json(self, pred: Callable[[dict[str, Any]], bool], timeout: float
                  ) -> dict[str, Any] | None:
        deadline = time.monotonic() + timeout
        with self.cond:
            while True:
                found = next((m for m in self.json if pred(m)), None)
                left = deadline - time.monotonic()
                if found is not None or left <= 0:
                    return found
                self.cond.wait(left)

    def running(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def _signal(self, sig: int) -> None:
        if self.proc is not None:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(self.proc.pid, sig)

    def kill(self) -> None:
        self._signal(signal.SIGKILL)
        if self.proc is not None:
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(timeout=10)
            if self.proc.stdout is not None:
                self.proc.stdout.close()

    def terminate(self, timeout: float) -> bool:
        """SIGTERM the group; whether the process ended within ``timeout`` (else SIGKILL)."""
        if not self.running():
            return True
        self._signal(signal.SIGTERM)
        try:
            assert self.proc is not None
            self.proc.wait(timeout=timeout)
            return True
        except subprocess.TimeoutExpired:
            self.kill()
            return False

    def tail(self) -> str:
        with self.cond:
            return " | ".join(list(self.lines)[-5:])


def group_usage(proc: Proc) -> dict[str, float]:
    """RSS (MiB), threads and sockets of every process in ``proc``'s group."""
    rss = threads = sockets = 0.0
    pgid = proc.proc.pid if proc.proc is not None else -1
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
            if int(stat.rsplit(")", 1)[1].split()[2]) != pgid:
                continue
            for line in Path(f"/proc/{pid}/status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    rss += int(line.split()[1]) / 1024
                elif line.startswith("Threads:"):
                    threads += int(line.split()[1])
            sockets += sum(1 for fd in os.listdir(f"/proc/{pid}/fd")
                           if os.readlink(f"/proc/{pid}/fd/{fd}").startswith("socket:"))
        except (OSError, ValueError, IndexError):
            continue
    return {"rss_mib": round(rss, 1), "threads": threads, "sockets": sockets}
