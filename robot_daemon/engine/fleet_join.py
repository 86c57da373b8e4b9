"""A robot joining a router (``--router``): checked at start, watched while it runs.

Before the daemon opens its own session it opens a small *check session* to the router, a
client logged in as the robot (``--user``… or the environment). That session:

- tells apart a router that does not answer from one that refuses the login, so start-up fails
  with one line naming which, and the fix;
- learns the router's Zenoh ID. A robot that protects its own endpoint (``--auth``/``--secure``)
  enforces access control on *every* link, its router's included, and Zenoh authenticates only
  the side that opens a link: the robot never learns a user name for its router, so with
  default-deny the router link matched no subject and nothing of the robot reached the fleet
  (issue #26). The robot's rules therefore trust its router by that ID
  (``access_control.subjects[].zids``): the router enforces the roles of everyone behind it.
  ``darwin router`` keeps one ID across restarts (:func:`stable_router_id`), so a restarted
  router is trusted again;
- after the daemon declared its ``alive`` token, looks for that token *through the router*. A
  robot the router cannot see (its login is not a ``robot`` identity there, so the router drops
  what it publishes) refuses to start with one line; later, :class:`RouterWatch` says once
  when the router loses sight of it and once when it sees it again.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import socket
import sys
import threading
import time
from collections.abc import Callable

import zenoh

from schemas.errors import DarwinError
from schemas.session import Credentials, client_config, endpoint_host_port

# How long the daemon waits for its router at start before it says it cannot reach it; later
# losses are retried for ever (Zenoh re-links by itself).
ROUTER_CONNECT_TIMEOUT_MS = 5000
# How long start-up waits for the router to show the robot's token (on a loaded machine the
# declaration crosses two links and a router: seconds at most).
VISIBLE_TIMEOUT_S = 10.0
WATCH_PERIOD_S = 2.0


class JoinError(DarwinError):
    """The robot cannot join its router: one line naming why and the fix."""


def join_router(conf: zenoh.Config, router: str, connect: list[str]) -> None:
    """Make ``conf`` (the daemon's peer session) join ``router``, failing at start when it
    cannot be reached. Gossip is off: a robot in a fleet talks only through its router, never
    straight to another robot it might hear about (the router is where access is controlled)."""
    conf.insert_json5("connect/endpoints", json.dumps([router, *connect]))
    conf.insert_json5("connect/timeout_ms", str(ROUTER_CONNECT_TIMEOUT_MS))
    conf.insert_json5("connect/exit_on_failure", "true")
    conf.insert_json5("scouting/gossip/enabled", "false")


def stable_router_id(listen: list[str]) -> str:
    """A Zenoh ID for ``darwin router`` that stays the same across restarts on the same
    machine and endpoints (robots with access control trust their router by it)."""
    seed = "|".join([socket.gethostname(), *sorted(listen)])
    digest = hashlib.sha256(seed.encode()).hexdigest()[:32]
    return "1" + digest[1:] if digest[0] == "0" else digest  # Zenoh refuses leading zeros


def _answers(router: str) -> bool:
    """Whether something accepts a TCP connection at the router's address."""
    if not router.startswith(("tcp/", "tls/", "ws/")):
        return False
    try:
        host, port = endpoint_host_port(router)
        with socket.create_connection((host, port), timeout=2.0):
            return True
    except (OSError, ValueError):
        return False


def _refusal(router: str, creds: Credentials | None) -> str:
    who = creds.user if creds is not None and creds.user else None
    if creds is not None and creds.cert:
        who = who or "the certificate's name"
    tls = router.startswith("tls/")
    if who:
        fix = (f"check {who}'s password or certificate, and that the router's identities list "
               f"{who} (`darwin users add {who} --role robot --password-file FILE --users "
               "ROUTER_USERS`)")
    else:
        fix = ("it requires a login: pass --user NAME --password-file FILE (or DARWIN_USER and "
               "DARWIN_PASSWORD_FILE) of an identity with the role robot there")
    if tls and (creds is None or not creds.ca):
        fix += "; a tls/ router also needs --ca CA (its `darwin certs` CA certificate)"
    elif not tls:
        fix += "; if it listens on tls/ (--secure), write --router tls/… and pass --ca CA"
    return f"the router at {router} answers but refused this robot's session: {fix}"


class RouterWatch:
    """The robot's check session to its router (see the module docstring)."""

    def __init__(self, router: str, creds: Credentials | None, lease_ms: int = 3000):
        self.router = router
        try:
            self.session = zenoh.open(client_config(router, lease_ms, creds or Credentials()))
        except zenoh.ZError:
            if _answers(router):
                raise JoinError(_refusal(router, creds)) from None
            raise JoinError(
                f"cannot reach the router at {router}: nothing answered; start it first "
                "(`darwin router --listen ENDPOINT`) or fix --router"
            ) from None
        self.login = creds.user if creds is not None and creds.user else None
        self.router_zids = [str(z) for z in self.session.info.routers_zid()]
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def sees(self, key: str, timeout: float = 2.0) -> bool:
        """Whether the router has ``key``'s liveliness token (asked through the router)."""
        try:
            replies = self.session.liveliness().get(key, timeout=timeout)
            return any(r.ok is not None for r in replies)
        except zenoh.ZError:
            return False

    def wait_visible(self, key: str, timeout: float = VISIBLE_TIMEOUT_S) -> None:
        """Start-up: the router must see ``key`` within ``timeout``, else :class:`JoinError`."""
        deadline = time.monotonic() + timeout
        while not self.sees(key, timeout=min(2.0, max(0.5, deadline - time.monotonic()))):
            if time.monotonic() >= deadline:
                who = self.login or "this robot's login"
                raise JoinError(
                    f"the router at {self.router} does not see this robot ({key} is not there "
                    f"through it after {timeout:g} s): it drops what a robot publishes unless "
                    f"its login has the role robot in the router's identities; log in as a "
                    f"robot identity (`darwin users add NAME --role robot --password-file FILE "
                    f"--users ROUTER_USERS`), not {who}"
                )
            time.sleep(0.2)

    def watch(self, key: str, say: Callable[[str], None] | None = None) -> None:
        """From now on, say once when the router loses sight of ``key`` and once when it
        sees it again (a router restart, a cut link)."""
        say = say or _say

        def loop() -> None:
            seen = True
            while not self._stop.wait(WATCH_PERIOD_S):
                now = self.sees(key)
                if now != seen:
                    seen = now
                    say(f"the router at {self.router} sees this robot again" if now else
                        f"the router at {self.router} does not see this robot: clients of the "
                        "router cannot reach it until it does (Zenoh rejoins by itself)")

        self._thread = threading.Thread(target=loop, name="router-watch", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=WATCH_PERIOD_S + 3.0)
        with contextlib.suppress(Exception):
            self.session.close()


def _say(line: str) -> None:
    print(f"darwin daemon: {line}", file=sys.stderr, flush=True)
