"""The arbiter: one queryable per verb under ``…/cmd/``, one queue to the motion thread.

A query is decoded in the Zenoh thread and handed to a worker; the worker queues it for the
motion thread, which checks the lease and runs the verb handler between bus transactions
(:meth:`Arbiter.apply_pending`), then the worker replies. Rejected commands never reach a
handler, so they never touch the bus. Clients' liveliness tokens tell when a holder vanished.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from robot_daemon.arbiter import verbs
from robot_daemon.arbiter.lease import Lease
from robot_daemon.arbiter.registry import REGISTRY, MotionContext, Reject, Request, needs_lease
from schemas import SCHEMA_VERSION
from schemas.errors import ErrorCode, ProtocolError
from schemas.keys import VERBS, Keys, verb_of
from schemas.messages import decode_dict, error_reply, ok_reply

log = logging.getLogger(__name__)

# Fields of a command payload that are not the verb's own.
_ENVELOPE = ("v", "client", "client_name")


@dataclass
class Pending:
    request: Request
    query: zenoh.Query
    deadline: float
    reply: bytes = b""
    ok: bool = False
    answered: bool = False


def parse_request(verb_name: str, payload: bytes | None) -> Request:
    """Decode a command payload or raise ``Reject`` naming what is wrong."""
    if not payload:
        raise Reject(ErrorCode.INVALID, "empty payload: send a msgpack map with v and client")
    try:
        d = decode_dict(payload)
    except ProtocolError as exc:
        raise Reject(ErrorCode.INVALID, str(exc)) from None
    if d.get("v") != SCHEMA_VERSION:
        raise Reject(
            ErrorCode.INVALID,
            f"schema version {d.get('v')!r} not supported (this daemon speaks {SCHEMA_VERSION})",
            "v",
        )
    client = d.get("client")
    if not isinstance(client, str) or not client:
        raise Reject(ErrorCode.INVALID, "missing field 'client' (the caller's client id)", "client")
    name = d.get("client_name")
    if not isinstance(name, str) and verb_name == "lease":
        name = d.get("name")  # the lease verb's own field is the human name
    fields_ = {k: v for k, v in d.items() if k not in _ENVELOPE}
    return Request(verb_name, client, name if isinstance(name, str) and name else client, fields_)


class Arbiter:
    def __init__(
        self,
        session: zenoh.Session,
        keys: Keys,
        lease: Lease,
        reply_timeout: float = 5.0,
    ) -> None:
        verbs.load_all()
        self.session = session
        self.keys = keys
        self.lease = lease
        self.reply_timeout = reply_timeout
        self._to_motion: queue.SimpleQueue[Pending] = queue.SimpleQueue()
        self._incoming: queue.SimpleQueue[zenoh.Query | None] = queue.SimpleQueue()
        self._done: queue.SimpleQueue[Pending | None] = queue.SimpleQueue()
        self._outstanding: dict[int, Pending] = {}
        self._lock = threading.Lock()
        self.counts = {"accepted": 0, "rejected": 0, "errors": 0}
        self.on_wakeup: Callable[[], None] | None = None  # the loop may wait for commands
        # The daemon's say on whether a command may run now (it raises Reject, e.g. while the
        # serial port is lost); checked before the lease and the handler.
        self.gate: Callable[[Request], None] | None = None
        self._queryables = [
            session.declare_queryable(keys.cmd(v), self._incoming.put, complete=True) for v in VERBS
        ]
        self._threads = [
            threading.Thread(target=self._intake, name="arbiter-intake", daemon=True),
            threading.Thread(target=self._replier, name="arbiter-reply", daemon=True),
        ]
        for t in self._threads:
            t.start()
        self._clients = session.liveliness().declare_subscriber(
            keys.clients_all, self._on_client, history=True
        )

    # -- Zenoh side --------------------------------------------------------------------------
    def _on_client(self, sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.DELETE:
            client = str(sample.key_expr).rsplit("/", 1)[-1]
            self.lease.client_gone(client)

    def _intake(self) -> None:
        """Decode queries and queue them for the motion thread, in arrival order."""
        while True:
            query = self._incoming.get()
            if query is None:
                return
            verb_name = verb_of(str(query.key_expr))
            try:
                payload = query.payload.to_bytes() if query.payload is not None else None
                req = parse_request(verb_name, payload)
            except Reject as r:
                self.counts["rejected"] += 1
                self._finish_query(query, False, error_reply(verb_name, r.code, r.message, r.field))
                continue
            pending = Pending(req, query, time.monotonic() + self.reply_timeout)
            with self._lock:
                self._outstanding[id(pending)] = pending
            self._to_motion.put(pending)
            if self.on_wakeup is not None:
                self.on_wakeup()

    def _replier(self) -> None:
        """Reply to what the motion thread applied; time out what it never took."""
        while True:
            try:
                pending = self._done.get(timeout=0.25)
            except queue.Empty:
                pending = None
            else:
                if pending is None:
                    return
            if pending is not None:
                self._reply(pending)
            now = time.monotonic()
            with self._lock:
                late = [p for p in self._outstanding.values() if p.deadline < now]
            for p in late:
                p.reply = error_reply(
                    p.request.verb,
                    ErrorCode.UNAVAILABLE,
                    f"the motion loop did not take the command within {self.reply_timeout:.0f} s "
                    "(is the serial port lost? see status.state)",
                )
                p.ok = False
                self.counts["errors"] += 1
                self._reply(p)

    def _reply(self, pending: Pending) -> None:
        with self._lock:
            if pending.answered:
                return
            pending.answered = True
            self._outstanding.pop(id(pending), None)
        self._finish_query(pending.query, pending.ok, pending.reply, pending.request.verb)

    def _finish_query(self, query: zenoh.Query, ok: bool, reply: bytes, verb: str = "") -> None:
        try:
            if ok:
                query.reply(self.keys.cmd(verb), reply)
            else:
                query.reply_err(reply)
        except Exception:
            log.exception("replying to a %s command failed", verb or "malformed")
        finally:
            with contextlib.suppress(Exception):
                query.drop()

    # -- motion-thread side ------------------------------------------------------------------
    def has_pending(self) -> bool:
        return not self._to_motion.empty()

    def apply_pending(self, ctx: MotionContext) -> int:
        """Run every queued command in arrival order; called by the motion thread between bus
        transactions. Returns how many ran."""
        n = 0
        while True:
            try:
                pending = self._to_motion.get_nowait()
            except queue.Empty:
                return n
            n += 1
            if not pending.answered:  # else it timed out: too late to apply it
                self._apply(pending, ctx)
                self._done.put(pending)

    def _apply(self, pending: Pending, ctx: MotionContext) -> None:
        req = pending.request
        try:
            handler = REGISTRY.get(req.verb)
            if handler is None:
                raise Reject(
                    ErrorCode.UNAVAILABLE,
                    f"verb {req.verb!r} is not available in this daemon build",
                )
            if self.gate is not None:
                self.gate(req)
            if needs_lease(req.verb, req.fields):
                self.lease.check(req.client)
            applied = handler(req, ctx)
            pending.reply, pending.ok = ok_reply(req.verb, applied), True
            self.counts["accepted"] += 1
        except Reject as r:
            pending.reply = error_reply(req.verb, r.code, r.message, r.field)
            self.counts["rejected"] += 1
        except Exception as exc:
            log.exception("verb %s failed", req.verb)
            pending.reply = error_reply(
                req.verb, ErrorCode.INTERNAL, f"{type(exc).__name__}: {exc} (a daemon bug)"
            )
            self.counts["errors"] += 1

    def fail_pending(self, message: str) -> None:
        """Answer every queued command with an error (the daemon is stopping)."""
        while True:
            try:
                pending = self._to_motion.get_nowait()
            except queue.Empty:
                return
            pending.reply = error_reply(pending.request.verb, ErrorCode.UNAVAILABLE, message)
            self._reply(pending)

    def close(self) -> None:
        for q in self._queryables:
            with contextlib.suppress(Exception):
                q.undeclare()
        with contextlib.suppress(Exception):
            self._clients.undeclare()
        self.fail_pending("the daemon is stopping")
        self._incoming.put(None)
        self._done.put(None)
        for t in self._threads:
            t.join(timeout=2.0)

    def status(self) -> dict[str, Any]:
        return {**self.counts, "lease": self.lease.status()}
