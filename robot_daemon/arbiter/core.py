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
import functools
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
from robot_daemon.arbiter.parking import ParkedAnswers
from robot_daemon.arbiter.registry import MotionContext, Reject, Request
from robot_daemon.arbiter.request import decode_command, execute, parse_request, request_from
from robot_daemon.arbiter.throttle import ArbiterLimits, Buckets
from schemas.commands import MAX_CLIENT_ID, SPEC, LeaseOp, op_of
from schemas.errors import CommandError, ErrorCode, ProtocolError, brief
from schemas.keys import VERBS, Keys, verb_of
from schemas.messages import error_reply, ok_reply
from schemas.query import answer, error_payload, request_bytes
from schemas.roles import ADMIN_VERBS, READ_OP_VERBS, is_admin_op, is_read_op

__all__ = ["Arbiter", "Pending", "decode_command", "execute", "parse_request", "request_from"]

log = logging.getLogger(__name__)

# Commands that are bus transactions in the motion thread: they share a per-tick budget.
BUS_VERBS = frozenset(v.name for v in SPEC.values() if v.bus)
# Halts are cheap (no bus I/O) and always first; this only bounds a flood of them per tick.
MAX_HALTS_PER_TICK = 64


def misdirected(key: str, served: str) -> None:
    """Refuse a query whose key is not exactly ``served``, the key of the queryable it reached
    (``Reject``, nothing run)."""
    if key != served:
        raise Reject(
            ErrorCode.INVALID,
            f"query on {key!r} reached the queryable of {served!r}: refused, nothing was run "
            "(a command goes to one robot's one verb, darwin/<robot>/cmd/<verb>, no wildcards)",
        )


@dataclass
class Pending:
    """A command waiting for the motion thread, with the query to answer when it is done."""

    request: Request
    query: zenoh.Query
    deadline: float
    reply: bytes = b""
    ok: bool = False
    answered: bool = False

    @property
    def on_bus(self) -> bool:
        return self.request.verb in BUS_VERBS


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
        self._reads: deque[Pending] = deque()  # register reads, within the bus share
        self._reading: dict[str, int] = {}  # client → its entries in _reads
        self._bus_credit = 0.0  # s of bus time client reads may use now
        self._credit_at = time.monotonic()
        self._read_cost = 0.002  # s, running estimate of one client read
        self._qlock = threading.Lock()
        # Each query with the key of the queryable it reached (see _intake).
        self._incoming: queue.SimpleQueue[tuple[str, zenoh.Query] | None] = queue.SimpleQueue()
        self._done: queue.SimpleQueue[Pending | None] = queue.SimpleQueue()
        self._outstanding: dict[int, Pending] = {}
        self._parked = ParkedAnswers(self._finish_query)  # throttled answers, held back
        self._lock = threading.Lock()
        lim = self.limits
        self._rate = Buckets(lim.client_rate, lim.client_burst)
        self._read_rate = Buckets(lim.client_read_rate, lim.client_read_burst)
        self.counts = {"accepted": 0, "rejected": 0, "errors": 0, "rate_limited": 0}
        self.on_wakeup: Callable[[], None] | None = None  # the loop may wait for commands
        # The daemon's say on whether a command may run now (it raises Reject, e.g. while the
        # serial port is lost); checked before the lease and the handler.
        self.gate: Callable[[Request], None] | None = None
        # Admin-only operations have keys of their own (schemas.roles): access control gives
        # those to admins alone, and the same operation on cmd/ is refused in _admit. Reads an
        # observer may send have read/<verb>, where anything but the read is refused.
        served = [*map(keys.cmd, VERBS), *map(keys.admin, ADMIN_VERBS)]
        served += map(keys.read, READ_OP_VERBS)
        self._queryables = [
            session.declare_queryable(key, functools.partial(self._arrived, key), complete=True)
            for key in served
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

    def _arrived(self, served: str, query: zenoh.Query) -> None:
        self._incoming.put((served, query))

    def _intake(self) -> None:
        """Check queries and queue them for the motion thread, in arrival order."""
        while True:
            item = self._incoming.get()
            if item is None:
                return
            served, query = item
            # The verb is the queryable's own, never read off the query's key: the envelope
            # does not name it, so a query whose key is not exactly this queryable's (a wildcard
            # such as darwin/*/cmd/led, or one Zenoh handed to the wrong queryable) would
            # otherwise run as whichever verb its key happens to end in.
            verb_name = verb_of(served)
            try:
                misdirected(str(query.key_expr), served)
                self._admit(query, verb_name)
            except Reject as r:
                if r.code == ErrorCode.RATE_LIMITED:
                    self.counts["rate_limited"] += 1
                    self._parked.hold(query, verb_name, r)
                    continue
                self.counts["rejected"] += 1
                self._finish_query(query, False, error_payload(verb_name, r))
            except ProtocolError as exc:
                self.counts["rejected"] += 1
                self._finish_query(query, False, error_payload(verb_name, exc))
            except Exception as exc:  # never lose the intake thread to one query
                self.counts["errors"] += 1
                self._finish_query(query, False, error_payload(verb_name, exc))

    def _admit(self, query: zenoh.Query, verb_name: str) -> None:
        d = decode_command(request_bytes(query, self.limits.max_payload_bytes))
        key = str(query.key_expr)
        if is_admin_op(verb_name, d) and key != self.keys.admin(verb_name):
            raise Reject(
                ErrorCode.FORBIDDEN,
                f"{verb_name} {op_of(verb_name, d)} needs the admin role and is served on "
                f"{self.keys.admin(verb_name)} only (the Robot client sends it there)",
            )
        if key == self.keys.read(verb_name) and not is_read_op(verb_name, d):
            raise Reject(
                ErrorCode.FORBIDDEN,
                f"{verb_name} {op_of(verb_name, d)} changes the robot and is served on "
                f"{self.keys.cmd(verb_name)} only; {key} serves reads",
            )
        client = d.get("client")
        client = client[:MAX_CLIENT_ID] if isinstance(client, str) else "?"
        urgent = verb_name == "halt"
        if verb_name == "lease" and d.get("op") == LeaseOp.RENEW:
            try:
                req = request_from(verb_name, d)
                self.lease.renew(req.client, req.token)  # pure state: answered here, at once
            except Reject:
                self._throttle(client, verb_name, d)  # a stranger's renewals are throttled
                raise
            self.counts["accepted"] += 1
            applied = {"op": "renew", "holder": self.lease.status(), "you": True}
            self._finish_query(query, True, ok_reply("lease", applied), "lease")
            return
        if not urgent:
            # Before the field checks: a client that floods bad commands is throttled too.
            self._throttle(client, verb_name, d)
        req = request_from(verb_name, d)
        pending = Pending(req, query, time.monotonic() + self.reply_timeout)
        with self._qlock:
            if urgent:
                self._urgent.append(pending)
            else:
                # Register reads wait for the bus share; so does whatever their client sends
                # next, so that one client's commands still run in the order it sent them.
                slow = _is_read(req) or self._reading.get(req.client, 0) > 0
                target = self._reads if slow else self._queue
                if len(target) >= self.limits.queue_size:
                    wait = self._drain_time(len(target), slow)
                    raise Reject(
                        ErrorCode.RATE_LIMITED,
                        f"busy: {len(target)} commands are waiting for the motion loop; "
                        f"retry in {wait:.2f} s",
                        retry_after=wait,
                    )
                target.append(pending)
                if slow:
                    self._reading[req.client] = self._reading.get(req.client, 0) + 1
        with self._lock:
            self._outstanding[id(pending)] = pending
        if self.on_wakeup is not None:
            self.on_wakeup()

    def _throttle(self, client: str, verb_name: str, d: dict[str, Any]) -> None:
        wait = self._rate.take(client)
        kind = "commands"
        if not wait and verb_name == "registers" and d.get("data") is None:
            wait, kind = self._read_rate.take(client), "register reads"
        if wait:
            raise Reject(
                ErrorCode.RATE_LIMITED,
                f"busy: client {brief(client)} sends {kind} faster than this daemon takes them "
                f"from one client; retry in {wait:.2f} s",
                retry_after=wait,
            )

    def _drain_time(self, queued: int, reads: bool) -> float:
        """About how long until the queue has room again (s)."""
        if reads:  # one read per ~read cost / share of the wall time
            return max(0.05, queued * self._read_cost / self.limits.bus_time_share)
        return max(0.01, queued / self.limits.commands_per_tick * 0.008)

    def _replier(self) -> None:
        """Reply to what the motion thread applied; time out what it never took."""
        wait = 0.25
        while True:
            try:
                pending = self._done.get(timeout=wait)
            except queue.Empty:
                pending = None
            else:
                if pending is None:
                    return
            if pending is not None:
                self._reply(pending)
            now = time.monotonic()
            wait = self._parked.release(now)
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
        # On the key the query came on: cmd/<verb>, or admin/<verb> for an admin-only operation.
        answer(query, str(query.key_expr) if ok else "", ok, reply)

    # -- motion-thread side ------------------------------------------------------------------
    def has_pending(self) -> bool:
        return bool(self._urgent or self._queue or self._reads)

    def _pop(self, source: deque[Pending]) -> Pending | None:
        with self._qlock:
            if not source:
                return None
            pending = source.popleft()
            if source is self._reads:
                left = self._reading.get(pending.request.client, 1) - 1
                if left > 0:
                    self._reading[pending.request.client] = left
                else:
                    self._reading.pop(pending.request.client, None)
            return pending

    def _run(self, pending: Pending, ctx: MotionContext) -> float:
        """Apply one command (unless it already timed out); returns the time it took."""
        t0 = time.perf_counter()
        if not pending.answered:
            self._apply(pending, ctx)
            self._done.put(pending)
        return time.perf_counter() - t0

    def apply_pending(self, ctx: MotionContext) -> int:
        """Run queued commands within this tick's budget; called by the motion thread between
        bus transactions. Returns how many ran; the rest waits for the next tick, in order.

        ``halt`` always runs, first. Then the commands in arrival order, at most
        ``commands_per_tick``, none started after ``work_budget_ms``, at most
        ``bus_commands_per_tick`` bus writes. Then at most one client register read, when the
        reads' share of bus time (``bus_time_share`` of the wall time, measured) allows: a read
        is a whole bus transaction in the tick, and a tick has little bus time to spare."""
        lim = self.limits
        start = time.perf_counter()
        budget = lim.work_budget_ms / 1000.0
        now = time.monotonic()
        self._bus_credit = min(
            lim.bus_burst_ms / 1000.0,
            self._bus_credit + (now - self._credit_at) * lim.bus_time_share,
        )
        self._credit_at = now
        n = 0
        for _ in range(MAX_HALTS_PER_TICK):
            pending = self._pop(self._urgent)
            if pending is None:
                break
            self._run(pending, ctx)
            n += 1
        ran = 0
        bus_left = lim.bus_commands_per_tick
        while ran < lim.commands_per_tick and (ran == 0 or time.perf_counter() - start < budget):
            with self._qlock:
                head = self._queue[0] if self._queue else None
            if head is None or (head.on_bus and bus_left <= 0):
                break
            pending = self._pop(self._queue)
            if pending is None:
                break
            took = self._run(pending, ctx)
            ran += 1
            if pending.on_bus:
                bus_left -= 1
                self._bus_credit -= took  # the holder's bus writes come first; reads yield
        if (
            self._reads
            and bus_left > 0
            and self._bus_credit > 0
            and time.perf_counter() - start < budget
        ):
            pending = self._pop(self._reads)
            if pending is not None:
                took = self._run(pending, ctx)
                ran += 1
                if _is_read(pending.request):
                    self._bus_credit -= took
                    self._read_cost = 0.8 * self._read_cost + 0.2 * took
        return n + ran

    def _apply(self, pending: Pending, ctx: MotionContext) -> None:
        req = pending.request
        try:
            if self.gate is not None:
                self.gate(req)
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
            taken = [*self._urgent, *self._queue, *self._reads]
            self._urgent.clear()
            self._queue.clear()
            self._reads.clear()
            self._reading.clear()
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
        self._parked.release(float("inf"))
        self._incoming.put(None)
        self._done.put(None)
        for t in self._threads:
            t.join(timeout=2.0)

    def status(self) -> dict[str, Any]:
        return {
            **self.counts,
            "queued": len(self._queue),
            "reads_queued": len(self._reads),
            "lease": self.lease.status(),
        }
