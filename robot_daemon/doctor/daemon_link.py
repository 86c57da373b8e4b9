"""The doctor's read-only view of a running daemon, through the key space alone: its
liveliness, its latest ``status`` and ``joints``, and register reads on the arbiter. The daemon
side depends on ``schemas``, never on a client library (``clients``), so this is the few lines
of one: the keys (``schemas.keys``), the messages (``schemas.messages``) and one query
(``schemas.query.ask``)."""

from __future__ import annotations

import functools
import threading
import time
import uuid
from types import TracebackType
from typing import Any, TypeVar

import zenoh

from schemas.errors import CommandTimeoutError, ProtocolError, RobotUnreachableError
from schemas.keys import Keys
from schemas.messages import Joints, Message, Status, command_payload, decode
from schemas.query import ask
from schemas.roles import command_key
from schemas.session import Target, connect

M = TypeVar("M", bound=Message)


class DaemonLink:
    """Status and joints as they arrive, and register reads; nothing is commanded."""

    def __init__(self, target: Target, name: str = "darwin doctor", timeout: float = 2.0) -> None:
        self.target = target
        self.name = name
        self.timeout = timeout
        self.keys = Keys(target.robot)
        self.client_id = f"doctor-{uuid.uuid4().hex[:12]}"
        self.session = connect(target, f"{name} cannot open a Zenoh session to {target.endpoint}")
        self._latest: dict[type[Message], Message] = {}
        self._arrived = threading.Condition()
        # The arbiter serves a client whose liveliness token it sees.
        self._token = self.session.liveliness().declare_token(self.keys.client(self.client_id))
        self._subs = [
            self.session.declare_subscriber(key, functools.partial(self._on_sample, kind))
            for key, kind in ((self.keys.status, Status), (self.keys.joints, Joints))
        ]

    def _on_sample(self, kind: type[Message], sample: zenoh.Sample) -> None:
        try:
            msg = decode(sample.payload.to_bytes(), kind)
        except ProtocolError:
            return  # another protocol: the versions check reports it
        with self._arrived:
            self._latest[kind] = msg
            self._arrived.notify_all()

    def alive(self, timeout: float = 1.0) -> bool:
        """True when the daemon's liveliness token is visible."""
        replies = self.session.liveliness().get(self.keys.alive, timeout=timeout)
        return any(r.ok is not None for r in replies)

    def latest(self, kind: type[M], timeout: float) -> M:
        """The newest ``kind`` message, waiting for the first up to ``timeout`` s."""
        deadline = time.monotonic() + timeout
        with self._arrived:
            while kind not in self._latest:
                left = deadline - time.monotonic()
                if left <= 0 or not self._arrived.wait(left):
                    raise CommandTimeoutError(
                        f"no {kind.TYPE} from {self.target.robot} within {timeout:.1f} s"
                    )
            msg = self._latest[kind]
        assert isinstance(msg, kind)
        return msg

    def registers(self, dxl_id: int, address: int, length: int) -> dict[str, Any]:
        """A register read through the arbiter (an operator's right; refused to observers)."""
        fields = {"id": dxl_id, "address": address, "length": length}
        payload = command_payload(self.client_id, client_name=self.name, **fields)

        def unreachable() -> Exception:
            return RobotUnreachableError(f"nobody answers registers at {self.target.endpoint}")

        key = command_key(self.keys, "registers", fields)
        return ask(self.session, key, payload, self.timeout, verb="registers",
                   unreachable=unreachable)

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        self._token.undeclare()
        self.session.close()

    def __enter__(self) -> DaemonLink:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
