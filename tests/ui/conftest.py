"""Fixtures of the UI tests: the app on a fixed scene (no robot), settings in a temp dir."""

from __future__ import annotations

import asyncio
import inspect
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from clients.tui import i18n
from clients.tui.app import DarwinApp
from tests.ui.scene import T0, load_scene


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> bool | None:
    """Run ``async def`` tests of this folder in a fresh event loop (Pilot needs one); no
    plugin needed."""
    if not inspect.iscoroutinefunction(pyfuncitem.obj):
        return None
    names = pyfuncitem._fixtureinfo.argnames
    asyncio.run(pyfuncitem.obj(**{n: pyfuncitem.funcargs[n] for n in names}))
    return True


@pytest.fixture(autouse=True)
def _english_after_each_test() -> Iterator[None]:
    # The language is process-wide (gettext); a test that switches it must not leak.
    yield
    i18n.set_language("en")


@pytest.fixture
def settings_file(tmp_path: Path) -> Path:
    return tmp_path / "config" / "darwin" / "tui.toml"


@pytest.fixture
def scene_app(settings_file: Path) -> Callable[..., DarwinApp]:
    """``scene_app(lang="en", tab="imu")`` → an app that loads the fixed scene when mounted."""

    def make(lang: str = "en", tab: str = "imu") -> DarwinApp:
        app = DarwinApp(connect=False, lang=lang, settings_path=settings_file, clock=lambda: T0)
        app.active_tab = tab
        app.call_later(load_scene, app)
        return app

    return make
