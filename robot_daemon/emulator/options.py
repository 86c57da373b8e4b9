"""The emulator's options that other programs declare too: ``darwin up`` and ``darwin daemon
--sim`` forward them to the ``darwin sim`` they start, without loading the emulator's settings
(:mod:`.settings`) for it."""

from __future__ import annotations

import argparse

# The plants that can stand behind the servos ([emulator] physics, --physics).
PLANTS = ("kinematic", "mujoco")


def add_physics_option(parser: argparse.ArgumentParser, help_start: str) -> None:
    """``--physics``: the one option choosing the plant (``darwin sim`` and ``darwin up``)."""
    parser.add_argument(
        "--physics",
        choices=PLANTS,
        help=f"{help_start}: kinematic (default) or mujoco (rigid-body physics; "
        "needs pip install -e '.[physics]')",
    )


def add_forwarded_options(parser: argparse.ArgumentParser, when: str = "") -> None:
    """``--sim-arg`` and ``--wire-timing``: what a program starting the emulator (``darwin
    daemon --sim``, ``darwin up``) forwards to it; ``when`` starts each help ("with --sim: ")."""
    parser.add_argument(
        "--sim-arg",
        action="append",
        default=[],
        metavar="ARG",
        help=f"{when}extra emulator argument (repeatable), e.g. --sim-arg=--drop=0.05",
    )
    parser.add_argument(
        "--wire-timing",
        action=argparse.BooleanOptionalAction,
        default=None,
        help=f"{when}model 1 Mbps wire time in the emulator",
    )
