"""The arbiter: one queryable per verb under ``…/cmd/``, one queue to the motion thread.

A query is checked in the intake thread, before anything reaches the motion thread: its size
(before decoding), its envelope, its fields against the verb's declaration, and the client's rate.
What passes is queued; the motion thread takes a bounded amount of it per tick
(:meth:`Arbiter.apply_pending`: ``halt`` first and always, then commands in arrival order within
a count, time and bus budget), checks the lease and runs the verb handler between bus
transactions; then the replier thread answers. Rejected commands never reach a handler, so they
never touch the bus. ``lease`` op=renew (the holder's heartbeat) is pure state and answered in
the intake thread, so a busy loop never makes a holder look silent.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from robot_daemon.arbiter import verbs
from robot_daemon.arbiter.lease import Lease
from robot_daemon.arbiter.registry import (
    REGISTRY,
    MotionContext,
    Reject,
    Request,
    check_fields,
    needs_lease,
)
from robot_daemon.arbiter.throttle import ArbiterLimits, Buckets
from schemas.commands import ENVELOPE, MAX_CLIENT_ID, MAX_NAME, LeaseOp
from schemas.errors import CommandError, ErrorCode, ProtocolError
from schemas.keys import VERBS, Keys, verb_of
from schemas.messages import error_reply, ok_reply
from schemas.query import MAX_PAYLOAD, answer, decode_request, error_payload, request_bytes

log = logging.getLogger(__name__)

# Commands that are bus transactions in the motion thread: they share a per-tick budget.
BUS_VERBS = frozenset({"registers", "torque", "led"})
# Halts are cheap (no bus I/O) and always first; this only bounds a flood of them per tick.
MAX_HALTS_PER_TICK = 64


@dataclass
class Pending:
    request: Request
    query: zenoh.Query
    deadline: float
    reply: bytes = b""
    ok: bool = False
    answered: bool = False

    @property
    def on_bus(self) -> bool:
        return self.request.verb in BUS_VERBS


def _text(d: dict[str, Any], name: str, limit: int, required: bool) -> str | None:
    value = d.get(name)
    if value is None and not required:
        return None
    if not isinstance(value, str) or not value or len(value) > limit:
        what = f"a string of 1..{limit} characters"
        raise Reject(ErrorCode.INVALID, f"field {name!r} must be {what}", name)
    return value


def parse_request(verb_name: str, payload: bytes | None, max_bytes: int = MAX_PAYLOAD) -> Request:
    """Decode a command payload and check its fields, or raise ``Reject`` naming what is
    wrong. Never lets any input through as anything but a ``Reject``."""
    try:
        d = decode_request(payload or b"", max_bytes)
    except CommandError as exc:
        raise Reject(exc.code, exc.message, exc.field) from None
    client = _text(d, "client", MAX_CLIENT_ID, required=True)
    assert client is not None
    name = _text(d, "client_name", MAX_NAME, required=False)
    token = _text(d, "lease_token", 64, required=False)
    fields_ = {k: v for k, v in d.items() if k not in ENVELOPE}
    check_fields(verb_name, fields_)
    if name is None and verb_name == "lease" and isinstance(fields_.get("name"), str):
        name = fields_["name"]  # the lease verb's own field is the human name
    return Request(verb_name, client, name or client, fields_, token)


def execute(req: Request, ctx: MotionContext, lease: Lease) -> dict[str, Any]:
    """Run a parsed request in the motion thread: the lease check, then the verb's handler.
    Raises ``CommandError`` (a refusal, nothing touched) or returns what was applied."""
    handler = REGISTRY.get(req.verb)
    if handler is None:
        raise Reject(ErrorCode.UNAVAILABLE, f"verb {req.verb!r} is not available in this build")
    if needs_lease(req.verb, req.fields):
        lease.check(req.client, req.token)
    return handler(req, ctx)


def _is_read(req: Request) -> bool:
    return req.verb == "registers" and req.fields.get("data") is None


class Arbiter:
    def __init__(
        self,
        session: zenoh.Session,
        keys: Keys,
        lease: Lease,
        reply_timeout: float | None = None,
        limits: ArbiterLimits | None = None,
    ) -> None:
        verbs.load_all()
        self.session = session
        self.keys = keys
        self.lease = lease
        self.limits = limits or ArbiterLimits()
        self.reply_timeout = reply_timeout or self.limits.reply_timeout
        self._urgent: deque[Pending] = deque()  # halt: served first, never throttled
        self._queue: deque[Pending] = deque()
        self._qlock = threading.Lock()
        self._incoming: queue.SimpleQueue[zenoh.Query | None] = queue.SimpleQueue()
        self._done: queue.SimpleQueue[Pending | None] = queue.SimpleQueue()
        self._outstanding: dict[int, Pending] = {}
        self._lock = threading.Lock()
        lim = self.limits
        self._rate = Buckets(lim.client_rate, lim.client_burst)
        self._reads = Buckets(lim.client_read_rate, lim.client_read_burst)
        self.counts = {"accepted": 0, "rejected": 0, "errors": 0, "rate_limited": 0}
        self.on_wakeup: Callable[[], None] | None = None  # the loop may wait for commands
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
        """Check queries and queue them for the motion thread, in arrival order."""
        while True:
            query = self._incoming.get()
            if query is None:
                return
            verb_name = verb_of(str(query.key_expr))
            try:
                self._admit(query, verb_name)
            except Reject as r:
                if r.code == ErrorCode.RATE_LIMITED:
                    self.counts["rate_limited"] += 1
                else:
                    self.counts["rejected"] += 1
                self._finish_query(query, False, error_payload(verb_name, r))
            except ProtocolError as exc:
                self.counts["rejected"] += 1
                self._finish_query(query, False, error_payload(verb_name, exc))
            except Exception as exc:  # never lose the intake thread to one query
                self.counts["errors"] += 1
                self._finish_query(query, False, error_payload(verb_name, exc))

    def _admit(self, query: zenoh.Query, verb_name: str) -> None:
        req = parse_request(verb_name, request_bytes(query, self.limits.max_payload_bytes))
        if req.verb == "lease" and req.fields.get("op") == LeaseOp.RENEW:
            self.lease.renew(req.client, req.token)  # pure state: answered here, at once
            self.counts["accepted"] += 1
            applied = {"op": "renew", "holder": self.lease.status(), "you": True}
            self._finish_query(query, True, ok_reply("lease", applied), "lease")
            return
        urgent = req.verb == "halt"
        if not urgent:
            self._throttle(req)
        pending = Pending(req, query, time.monotonic() + self.reply_timeout)
        with self._qlock:
            if urgent:
                self._urgent.append(pending)
            elif len(self._queue) >= self.limits.queue_size:
                raise Reject(
                    ErrorCode.RATE_LIMITED,
                    f"busy: {len(self._queue)} commands are waiting for the motion loop; "
                    f"retry in {self._drain_time():.2f} s",
                    retry_after=self._drain_time(),
                )
            else:
                self._queue.append(pending)
        with self._lock:
            self._outstanding[id(pending)] = pending
        if self.on_wakeup is not None:
            self.on_wakeup()

    def _throttle(self, req: Request) -> None:
        wait = self._rate.take(req.client)
        kind = "commands"
        if not wait and _is_read(req):
            wait, kind = self._reads.take(req.client), "register reads"
        if wait:
            raise Reject(
                ErrorCode.RATE_LIMITED,
                f"busy: client {req.client} sends {kind} faster than this daemon takes them "
                f"from one client; retry in {wait:.2f} s",
                retry_after=wait,
            )

    def _drain_time(self) -> float:
        # Ticks needed to take the queue at the per-tick count, as seconds at 8 ms a tick.
        return max(0.01, len(self._queue) / self.limits.commands_per_tick * 0.008)

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
        answer(query, self.keys.cmd(verb) if ok else "", ok, reply)

    # -- motion-thread side ------------------------------------------------------------------
    def has_pending(self) -> bool:
        return bool(self._urgent or self._queue)

    def _next(self, bus_left: int, halts: int) -> Pending | None:
        with self._qlock:
            if self._urgent and halts < MAX_HALTS_PER_TICK:
                return self._urgent.popleft()
            if self._queue and (bus_left > 0 or not self._queue[0].on_bus):
                return self._queue.popleft()
            return None

    def apply_pending(self, ctx: MotionContext) -> int:
        """Run queued commands in arrival order within this tick's budget (``halt`` always,
        first); called by the motion thread between bus transactions. Returns how many ran.
        What is left waits for the next tick, still in order."""
        lim = self.limits
        start = time.perf_counter()
        budget = lim.work_budget_ms / 1000.0
        n = urgent = 0
        bus_left = lim.bus_commands_per_tick
        while True:
            with self._qlock:
                has_urgent = bool(self._urgent) and urgent < MAX_HALTS_PER_TICK
            if not has_urgent and (
                n - urgent >= lim.commands_per_tick
                or (n > urgent and time.perf_counter() - start >= budget)
            ):
                return n
            pending = self._next(bus_left, urgent)
            if pending is None:
                return n
            n += 1
            if pending.request.verb == "halt":
                urgent += 1
            elif pending.on_bus:
                bus_left -= 1
            if not pending.answered:  # else it timed out: too late to apply it
                self._apply(pending, ctx)
                self._done.put(pending)

    def _apply(self, pending: Pending, ctx: MotionContext) -> None:
        req = pending.request
        try:
            applied = execute(req, ctx, self.lease)
            pending.reply, pending.ok = ok_reply(req.verb, applied), True
            self.counts["accepted"] += 1
        except CommandError as r:
            pending.reply = error_payload(req.verb, r)
            self.counts["rejected"] += 1
        except Exception as exc:
            log.exception("verb %s failed", req.verb)
            pending.reply = error_payload(req.verb, exc)
            self.counts["errors"] += 1

    def fail_pending(self, message: str, code: ErrorCode = ErrorCode.UNAVAILABLE) -> int:
        """Answer every queued command with an error (the daemon is stopping, or the port is
        lost and nothing queued may run later); returns how many."""
        with self._qlock:
            taken = [*self._urgent, *self._queue]
            self._urgent.clear()
            self._queue.clear()
        for pending in taken:
            pending.reply = error_reply(pending.request.verb, code, message)
            pending.ok = False
            self._reply(pending)
        return len(taken)

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
        return {**self.counts, "queued": len(self._queue), "lease": self.lease.status()}
