"""The world in ``darwin sim``: options, and what runs once the emulator is up.

With the emulator's ``--control-listen`` the world serves its ops and publishes on that session.
With ``--world-connect ENDPOINT`` (what ``darwin daemon --sim`` passes: the daemon's own
endpoint) it opens a Zenoh client session to it — retrying until the daemon listens — and serves
the control ops (world and emulator ones) and publishes there, so the daemon's ``sim`` camera
source and every client of the daemon reach the world.

Publishes the :class:`~schemas.messages.World` message on ``Keys(robot).sim_world`` at
``[world] publish_hz``.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import zenoh

from config.loader import load_all
from robot_daemon.plant import world_ops
from robot_daemon.plant.world import SimWorld, make_world
from robot_daemon.plant.world_settings import WorldSettings
from schemas import qos
from schemas.keys import Keys
from schemas.messages import encode

if TYPE_CHECKING:
    from robot_daemon.emulator.emulator import Emulator

log = logging.getLogger(__name__)


def _pair(text: str, n: int) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not {n} comma-separated numbers") from None
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"{text!r} is not {n} comma-separated numbers")
    return values


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("simulated world")
    g.add_argument("--no-world", action="store_true", help="run the bus emulator without a world")
    g.add_argument(
        "--world-connect",
        metavar="ENDPOINT",
        help="Zenoh endpoint (the daemon's) where the world publishes and serves its ops",
    )
    g.add_argument("--ball", type=lambda t: _pair(t, 2), help="ball start X,Y (m)")
    g.add_argument("--no-ball", action="store_true", help="start without a ball on the field")
    g.add_argument(
        "--robot-pose", type=lambda t: _pair(t, 3), help="robot start X,Y,YAW_DEG (m, degrees)"
    )


def world_from_args(args: argparse.Namespace, plant: str = "kinematic") -> Any:
    """The world for ``plant`` (the emulator's ``physics`` setting), placed as ``args`` say."""
    config = load_all(getattr(args, "config", None))
    settings = WorldSettings.from_config(config.get("world", {}))
    world = make_world(plant, settings, config, seed=getattr(args, "seed", None) or None)
    pose = getattr(args, "robot_pose", None)
    if pose:
        world.place_robot(pose[0], pose[1], math.radians(pose[2]))
    if getattr(args, "no_ball", False):
        world.remove_ball()
    elif getattr(args, "ball", None):
        world.place_ball(*args.ball)
    return world


def attach(
    emulator: Emulator, args: argparse.Namespace, session: zenoh.Session | None
) -> Callable[[], None] | None:
    if getattr(args, "no_world", False):
        return None
    world = world_from_args(args, emulator.settings.physics)
    world.attach(emulator)
    emulator.world = world  # type: ignore[attr-defined]  # the control ops find it here
    world_ops.install()
    robot = getattr(args, "robot", None) or "op1"
    link = WorldLink(emulator, world, robot, session, getattr(args, "world_connect", None))
    link.start()
    return link.close


class WorldLink:
    """The world on Zenoh: its session (given or connected), control ops, World publication."""

    def __init__(
        self,
        emulator: Emulator,
        world: SimWorld,
        robot: str,
        session: zenoh.Session | None,
        connect: str | None,
    ) -> None:
        self.emulator = emulator
        self.world = world
        self.keys = Keys(robot)
        self.session = session
        self.connect = connect
        self._own_session: zenoh.Session | None = None
        self._queryable: Any = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sim-world", daemon=True)

    def start(self) -> None:
        if self.session is None and not self.connect:
            return  # no Zenoh: the world still moves the robot and feeds the IMU
        self._thread.start()

    def _open(self) -> zenoh.Session | None:
        from robot_daemon.emulator.control_service import serve_control
        from schemas.session import open_client

        delay = 0.05
        while not self._stop.is_set():
            try:
                # _open runs only with an endpoint to connect to (see start()).
                session = open_client(self.connect)  # type: ignore[arg-type]
            except Exception as exc:  # the daemon is not listening yet
                log.debug("world: %s not reachable yet (%s)", self.connect, exc)
                self._stop.wait(delay)
                delay = min(delay * 2, 1.0)
                continue
            self._own_session = session
            self._queryable = serve_control(session, self.keys.robot, self.emulator)
            log.info("world connected to %s (robot %s)", self.connect, self.keys.robot)
            return session
        return None

    def _run(self) -> None:
        session = self.session or self._open()
        if session is None:
            return
        pub = session.declare_publisher(
            self.keys.sim_world, **qos.for_key(self.keys.sim_world).kwargs()
        )
        period = 1.0 / max(0.5, self.world.settings.publish_hz)
        try:
            while not self._stop.wait(period):
                pub.put(encode(self.world.snapshot()))
        except Exception as exc:  # the session closed under us at shutdown
            log.debug("world publisher stopped: %s", exc)
        finally:
            with contextlib.suppress(Exception):
                pub.undeclare()

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=3.0)
        if self._queryable is not None:
            with contextlib.suppress(Exception):
                self._queryable.undeclare()
        if self._own_session is not None:
            with contextlib.suppress(Exception):
                self._own_session.close()
