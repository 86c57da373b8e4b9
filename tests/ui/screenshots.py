"""Write the screenshots (SVG) of every tab on the fixed scene, shown in docs/tui.md:
``python -m tests.ui.screenshots [OUT_DIR]`` (default ``docs/screenshots``)."""

from __future__ import annotations

import asyncio
import sys
import tempfile
from pathlib import Path

from clients.tui.app import TABS, DarwinApp
from tests.ui.scene import T0, load_scene

SIZE = (120, 36)


async def shoot(tab: str, out: Path, keys: tuple[str, ...] = (), name: str = "") -> Path:
    settings = Path(tempfile.mkdtemp()) / "tui.toml"
    app = DarwinApp(connect=False, lang="en", settings_path=settings, clock=lambda: T0)
    app.active_tab = tab
    async with app.run_test(size=SIZE) as pilot:
        load_scene(app)
        await pilot.pause(0.3)
        app.redraw(force=True)
        if keys:
            await pilot.press(*keys)
        await pilot.pause(0.2)
        path = out / f"{name or tab}.svg"
        path.write_text(app.export_screenshot(title=f"darwin tui: {name or tab}"))
    return path


async def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for tab, _title in TABS:
        print(await shoot(tab, out))
    print(await shoot("pose", out, ("m", "right_square_bracket", "s"), "pose-manipulate"))
    print(await shoot("imu", out, ("c",), "connect"))
    print(await shoot("walk", out, ("f1",), "help"))


if __name__ == "__main__":
    asyncio.run(main(Path(sys.argv[1] if len(sys.argv) > 1 else "docs/screenshots")))
