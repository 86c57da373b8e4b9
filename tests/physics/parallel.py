"""Independent seeded tries of a physics test, spread over the machine's cores.

Each try builds its own rig from its seed and shares nothing, so the result does not depend on
which process ran it; lock-step simulation is CPU-bound and the rest of the suite runs on one
core, so two cores halve these tests. Workers are spawned (not forked): the parent holds
threads (Zenoh, the camera) that a fork would copy half-alive."""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

R = TypeVar("R")


def tries(fn: Callable[..., R], args: Sequence[tuple[Any, ...]]) -> list[R]:
    """``[fn(*a) for a in args]``, in order, run in up to one process per core. ``fn`` must be
    importable (a module-level function) and its results picklable."""
    workers = min(len(args), os.cpu_count() or 1)
    if workers <= 1:
        return [fn(*a) for a in args]
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        return list(pool.map(fn, *zip(*args, strict=True)))
