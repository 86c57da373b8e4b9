"""A legacy TCP JSON client written from the protocol spec (legacy-protocol.md and appendix A of
the original report), not from the gateway's code: it frames with ``struct`` in whichever
convention it is told to use and reads replies in that same convention.

    with LegacyClient(host, port, order="little", counted=True) as c:
        c.send({"monitor": {"motors": 1}})
        msg = c.recv_until(lambda m: "monitor" in m)
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import socket
import struct
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

from tests.fixtures.emulator import darwin_command

ORDERS = ("big", "little", "ascii")
CONVENTIONS = tuple((order, counted) for order in ORDERS for counted in (False, True))

# Every example message of appendix A, verbatim (client → server ones).
APPENDIX_A_CLIENT_EXAMPLES = (
    '{"monitor":{ "accelerometer":0,"camera":0,"gyroscope":0,"motors":0 }}',
    '{"monitor":{ "accelerometer":1 }}',
    '{"operate":{ "all":0,"id":3,"position":27 }}',
    '{"led":{ "id":26,"ledcolor":[182,35,28] }}',
    '{"orchestrate": [ {"page":9, "type":5}, {"page":325, "type":1}, {"time":20} ]}',
    '{"orchestrate":{ "status":0 }}',
    '{"walk":{ "a":0, "stop":0,"x":10, "y":0 }}',
    '{"playball":{ "status":1 }}',
)

# Vocabulary for generated messages: the protocol's tags and fields, and some that are not.
FUZZ_TAGS = ("monitor", "operate", "led", "orchestrate", "walk", "playball", "error", "")
FUZZ_FIELDS = (
    "all",
    "id",
    "position",
    "ledcolor",
    "status",
    "page",
    "type",
    "time",
    "a",
    "x",
    "y",
    "stop",
    "accelerometer",
    "camera",
    "gyroscope",
    "motors",
    "period",
)


def header(body_len: int, order: str = "big", counted: bool = False) -> bytes:
    """A size header as the spec says, in one of its conventions."""
    size = body_len + (4 if counted else 0)
    if order == "ascii":
        return b"%04d" % size
    return struct.pack(">I" if order == "big" else "<I", size)


def frame(body: str | bytes, order: str = "big", counted: bool = False) -> bytes:
    data = body.encode("utf-8") if isinstance(body, str) else body
    return header(len(data), order, counted) + data


class LegacyClient:
    def __init__(
        self,
        host: str,
        port: int,
        order: str = "big",
        counted: bool = False,
        timeout: float = 10.0,
        rcvbuf: int | None = None,
    ) -> None:
        if order not in ORDERS:
            raise ValueError(f"order must be one of {ORDERS}")
        self.order = order
        self.counted = counted
        self.timeout = timeout
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        if rcvbuf is not None:
            # Before connect, so the window the server sees is small: a client that stops
            # reading fills up quickly.
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.sock.settimeout(timeout)
        self.sock.connect((host, port))
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._buf = b""
        self.received: list[dict[str, Any]] = []

    def __enter__(self) -> LegacyClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()

    # -- framing, from the spec ----------------------------------------------------------------
    def header(self, body_len: int) -> bytes:
        return header(body_len, self.order, self.counted)

    def size_of(self, header: bytes) -> int:
        if self.order == "ascii":
            size = int(header.decode("ascii"))
        else:
            size = struct.unpack(">I" if self.order == "big" else "<I", header)[0]
        return size - (4 if self.counted else 0)

    def frame(self, body: str | bytes) -> bytes:
        return frame(body, self.order, self.counted)

    def send(self, message: dict[str, Any] | str | bytes) -> None:
        body = message if isinstance(message, str | bytes) else json.dumps(message)
        self.sock.sendall(self.frame(body))

    def send_raw(self, data: bytes) -> None:
        self.sock.sendall(data)

    # -- receiving -----------------------------------------------------------------------------
    def _fill(self, n: int, deadline: float) -> bool:
        while len(self._buf) < n:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"no complete message within {self.timeout:g} s")
            ready, _, _ = select.select([self.sock], [], [], remaining)
            if not ready:
                continue
            chunk = self.sock.recv(65536)
            if not chunk:
                return False
            self._buf += chunk
        return True

    def recv(self, timeout: float | None = None) -> dict[str, Any] | None:
        """The next message, or None when the server closed the connection."""
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        if not self._fill(4, deadline):
            return None
        size = self.size_of(self._buf[:4])
        if not self._fill(4 + size, deadline):
            return None
        body, self._buf = self._buf[4 : 4 + size], self._buf[4 + size :]
        msg = json.loads(body.decode("utf-8"))
        self.received.append(msg)
        return msg

    def recv_until(
        self, predicate: Callable[[dict[str, Any]], bool], timeout: float | None = None
    ) -> dict[str, Any]:
        """Read until a message satisfies ``predicate`` (others are kept in ``received``)."""
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        while True:
            msg = self.recv(max(0.0, deadline - time.monotonic()))
            if msg is None:
                raise ConnectionError("the server closed the connection")
            if predicate(msg):
                return msg

    def recv_error(self, timeout: float | None = None) -> dict[str, Any]:
        return self.recv_until(lambda m: "error" in m, timeout)["error"]

    def closed_by_server(self, timeout: float | None = None) -> bool:
        """True once the server closes (messages before that are kept in ``received``)."""
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        try:
            while True:
                if self.recv(max(0.0, deadline - time.monotonic())) is None:
                    return True
        except (ConnectionResetError, BrokenPipeError):
            return True
        except TimeoutError:
            return False


@contextlib.contextmanager
def start_gateway(
    endpoint: str, robot: str, settings: dict[str, Any] | None = None, tmp_dir: str = "/tmp"
) -> Iterator[GatewayProcess]:
    """Run ``darwin gateway`` on a free port against a running daemon, with ``[gateway]``
    settings written to a user config file; the process is killed when the block ends."""
    lines = ["[gateway]", 'listen = "127.0.0.1:0"']
    lines += [f"{k} = {json.dumps(v)}" for k, v in (settings or {}).items()]
    fd, path = tempfile.mkstemp(suffix=".toml", prefix="gateway-", dir=tmp_dir)
    with os.fdopen(fd, "w") as f:
        f.write("\n".join(lines) + "\n")
    cmd = darwin_command("gateway", "--connect", endpoint)
    cmd += ["--robot", robot, "--config", path]
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=dict(os.environ, PYTHONUNBUFFERED="1"),
        start_new_session=True,
    )
    gw = GatewayProcess(proc)
    try:
        line = gw.wait_line("gateway: ", 30.0)
        host, _, port = line.split(" ", 1)[1].strip().rpartition(":")
        gw.host, gw.port = host, int(port)
        yield gw
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=5)
        gw.close()
        os.unlink(path)


class GatewayProcess:
    """A ``darwin gateway`` child: its address and every line it printed."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.proc = proc
        self.host = "127.0.0.1"
        self.port = 0
        self.lines: list[str] = []
        self._cond = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def close(self) -> None:
        """After the process ended: finish reading its output and close the pipe."""
        self._reader.join(timeout=5)
        if self.proc.stdout is not None:
            self.proc.stdout.close()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self._cond:
                self.lines.append(line.rstrip("\n"))
                self._cond.notify_all()
        with self._cond:
            self.lines.append("")  # end of output
            self._cond.notify_all()

    def wait_line(self, needle: str, timeout: float) -> str:
        """The first line containing ``needle`` (waits for it)."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                for line in self.lines:
                    if needle in line:
                        return line
                if self.proc.poll() is not None and self.lines and self.lines[-1] == "":
                    raise RuntimeError("gateway exited:\n" + "\n".join(self.lines))
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise TimeoutError(
                        f"gateway printed no line with {needle!r} within {timeout:g} s:\n"
                        + "\n".join(self.lines)
                    )
                self._cond.wait(remaining)

    def client(self, **kwargs: Any) -> LegacyClient:
        return LegacyClient(self.host, self.port, **kwargs)
