"""Verb handler modules. Every module in this package is imported by :func:`load_all`, so a new
verb is one new module with ``@verb`` functions, and no list to edit."""

from __future__ import annotations

import importlib
import pkgutil


def load_all() -> None:
    for info in pkgutil.iter_modules(__path__):
        importlib.import_module(f"{__name__}.{info.name}")
