"""The Textual app (``DarwinApp``), which the CLI and the tests both build.

Telemetry arrives through the link's inbox (one wake-up message however many samples wait);
the handler only stores it in the model. A timer (~15 Hz) draws what changed, and only in the
tab that shows, so 125 Hz streams cost the screen nothing more than 15 redraws a second.
"""

from __future__ import annotations

import contextlib
import functools
import gc
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import TabbedContent, TabPane

from clients.tui import app_fleet, i18n
from clients.tui.app_commands import CommandRouter, daemon_robot_config
from clients.tui.connect import ConnectScreen, RobotFinder
from clients.tui.help import HelpScreen
from clients.tui.i18n import N_, _
from clients.tui.link import CommandDone, Link
from clients.tui.messages import (
    LinkChanged,
    LinkInfo,
    LinkState,
    Telemetry,
    TelemetryReady,
    VersionNotice,
)
from clients.tui.model import Model
from clients.tui.settings import Settings, default_path
from clients.tui.tabs.actions import ActionsTab
from clients.tui.tabs.base import SendCommand, TabView, role_at_least
from clients.tui.tabs.behaviours import BehavioursTab
from clients.tui.tabs.camera import CameraTab
from clients.tui.tabs.imu import ImuTab
from clients.tui.tabs.log import LogTab
from clients.tui.tabs.motors import MotorsTab
from clients.tui.tabs.pose import PoseTab
from clients.tui.tabs.walk import WalkTab
from clients.tui.widgets.header import RobotHeader
from clients.tui.widgets.keybar import KeyBar
from config.loader import RobotConfig, load_robot
from schemas.errors import ClientError, ConfigError
from schemas.messages import Event
from schemas.roles import Role, allows
from schemas.session import Credentials

RENDER_HZ = 15.0
TABS: tuple[tuple[str, str], ...] = (
    ("imu", N_("IMU")),
    ("motors", N_("Motors")),
    ("pose", N_("Pose")),
    ("camera", N_("Camera")),
    ("walk", N_("Walk")),
    ("behaviours", N_("Behaviours")),
    ("log", N_("Log")),
    ("actions", N_("Actions")),
)


def settle_heap() -> None:
    """Once the screen is built, leave everything alive now out of later full collections
    (``gc.freeze``), as the daemon does after its start. A full collection holds the
    interpreter for as long as it takes to walk every object: with Textual's on a loaded
    machine that was 1-3 s, and the lease renewals, sent from a thread of this process,
    stopped meanwhile ("holder silent"). No collection first: that would be the same pause,
    and what is garbage now is collected after :meth:`DarwinApp.on_unmount` unfreezes."""
    gc.freeze()


def tab_view(screen: Screen[Any], tab_id: str) -> TabView | None:
    """The view of the tab ``tab_id`` on ``screen``, if it has one (composed)."""
    views = screen.query(f"TabView#{tab_id}")
    return views.first(TabView) if views else None


# The tab classes by their TAB_ID: those that draw the robot's joints also take its config.
_ROBOT_TABS: dict[str, type[MotorsTab | PoseTab]] = {t.TAB_ID: t for t in (MotorsTab, PoseTab)}
_MODEL_TABS: dict[str, type[TabView]] = {
    t.TAB_ID: t for t in (ImuTab, CameraTab, WalkTab, BehavioursTab, ActionsTab, LogTab)
}


class MainScreen(Screen[None]):
    """Header, the tabs, the key bar. Composed again when the language changes.

    Only the tab that shows is composed with the screen; another is composed the first time it
    is shown (:meth:`open_tab`) and stays, keeping its state. Composing all eight cost CPU at
    every start (on the robot's Atom too) for views a session may never open; each draws from
    the model only, so one composed later shows what it would have shown composed at start.
    """

    def compose(self) -> ComposeResult:
        app = self.app
        assert isinstance(app, DarwinApp)
        yield RobotHeader(id="header")
        with TabbedContent(initial=f"pane-{app.active_tab}", id="tabs"):
            for n, (tab_id, title) in enumerate(TABS, 1):
                with TabPane(f"{n} {_(title)}", id=f"pane-{tab_id}"):
                    if tab_id == app.active_tab:
                        yield app.make_tab(tab_id)
        yield KeyBar()

    async def open_tab(self, tab_id: str) -> TabView:
        """The tab's view, composed into its pane first if it has not been, and mounted (its
        children too) when this returns."""
        app = self.app
        assert isinstance(app, DarwinApp)
        view = tab_view(self, tab_id)
        if view is None:
            view = app.make_tab(tab_id)
            await self.query_one(f"#pane-{tab_id}", TabPane).mount(view)
            # What the new view allocated joins the heap left out of full collections, as the
            # tabs composed at start did (settle_heap says why).
            app.call_after_refresh(settle_heap)
        return view

    def on_mount(self) -> None:
        app = self.app
        assert isinstance(app, DarwinApp)
        app.redraw(force=True)


class DarwinApp(App[None]):
    """The app, ready to ``run()`` (CLI) or ``run_test()`` (tests). ``connect=False`` starts
    without a link, for a fixed scene fed by posting messages; ``clock`` stamps the UI's own
    log lines (a fixed one keeps snapshots still). Its commands and their replies are
    :mod:`clients.tui.app_commands`, the robots at its endpoint :mod:`clients.tui.app_fleet`."""

    TITLE = "darwin tui"
    ENABLE_COMMAND_PALETTE = False  # its texts are Textual's, untranslated; help has every key
    CSS = """
    TabbedContent { height: 1fr; }
    TabbedContent > ContentSwitcher { height: 1fr; }
    TabPane { padding: 0; height: 1fr; }
    """
    BINDINGS = [
        Binding("ctrl+x,exclamation_mark", "halt", N_("HALT"), priority=True),
        Binding("l", "lease", N_("Lease take/release")),
        Binding("c", "connect", N_("Connect")),
        # Not on the key bar (Help must stay there at 80 columns); in the help screen.
        Binding("f3", "next_robot", N_("Next live robot"), show=False),
        # After the CM-730's reset button (header [servos_off]): power the servos again.
        Binding("P", "power", N_("Power the servos (admin)"), show=False),
        Binding("f1,question_mark", "help", N_("Help")),
        Binding("f2", "language", N_("Language")),
        Binding("ctrl+q", "quit", N_("Quit"), priority=True),
        *(
            Binding(str(n), f"show_tab('{tab_id}')", N_("Show tab"), show=False)
            for n, (tab_id, _t) in enumerate(TABS, 1)
        ),
    ]

    def __init__(
        self,
        *,
        endpoint: str | None = None,
        robot: str | None = None,
        name: str | None = None,
        lang: str | None = None,
        settings_path: Path | None = None,
        connect: bool = True,
        ask: bool = False,
        robot_config: RobotConfig | None = None,
        clock: Callable[[], float] = time.time,
        credentials: Credentials | None = None,
    ) -> None:
        super().__init__()
        self.clock = clock
        self.settings_path = settings_path or default_path()
        saved = Settings.load(self.settings_path)
        self.settings = Settings(
            endpoint=endpoint or saved.endpoint,
            robot=robot or saved.robot,
            name=name or saved.name or "tui",
            lang=lang or saved.lang,
        )
        i18n.set_language(lang or saved.lang or i18n.from_environment())
        self.model = Model()
        self.robot_config = robot_config or load_robot()
        self.link = Link(self, self.settings.name, credentials)
        self.link_info = LinkInfo(LinkState.IDLE, self.settings.endpoint, self.settings.robot)
        self.active_tab = TABS[0][0]
        self._connect_on_mount = connect
        # The live robots at an endpoint (connect screen, F3); None on a fixed scene (tests
        # may set a fixed list).
        self.find_robots: RobotFinder | None = (
            functools.partial(app_fleet.find_robots, self.link) if connect else None
        )
        self.command_router = CommandRouter(
            self.link, self.model, self.notify, self.local_event, self._config_reply
        )
        self._ask = ask
        self._seen: dict[str, int] = {}
        self._recorder: Any = None
        # Where the running recording writes (None: none runs), for a Log tab composed again.
        self.recording_to: str | None = None

    # -- composition -----------------------------------------------------------------------------
    def make_tab(self, tab_id: str) -> TabView:
        if (drawn := _ROBOT_TABS.get(tab_id)) is not None:
            return drawn(self.model, self.robot_config)
        if (tab := _MODEL_TABS.get(tab_id)) is not None:
            return tab(self.model)
        raise ValueError(f"unknown tab {tab_id!r}; tabs are {', '.join(t for t, _ in TABS)}")

    def on_mount(self) -> None:
        self.push_screen(MainScreen())
        self.set_interval(1.0 / RENDER_HZ, self.redraw)
        self.call_after_refresh(settle_heap)
        if self._ask:
            self.action_connect()
        elif self._connect_on_mount:
            self.connect(self.settings)

    def on_unmount(self) -> None:
        self.stop_recording()
        self.link.close()
        gc.unfreeze()  # a process that goes on (a test run) collects all of its heap again

    def connect(self, settings: Settings) -> None:
        try:
            self.link.name = settings.name
            self.link.connect(settings.endpoint, settings.robot)
        except ValueError as exc:
            self.notify(str(exc), severity="error", timeout=8)
            return
        self.settings = settings

    # -- commands (where each reply goes: clients/tui/app_commands.py) ---------------------------
    def on_send_command(self, message: SendCommand) -> None:
        self.command_router.send(message)

    def on_command_done(self, message: CommandDone) -> None:
        if not self.screen_stack:
            return  # the app is closing: a reply that comes in now has nowhere to be shown
        self.command_router.done(message, self._reply_to_tab)

    def _reply_to_tab(self, tab_id: str, reply: Callable[[TabView], None]) -> bool:
        """Hand a reply to the view of the tab that sent the command: on the screen on top (the
        offsets editor has its own), else on the main screen, under a dialog too. The main
        screen's tab may not be composed: the screen was composed again (F2) while the command
        was on its way. It is composed for the reply, which may change what it shows later (a
        page list, a page opened, the gait). False when no such tab is left."""
        main = self.main_screen()
        for screen in (self.screen, main):
            view = tab_view(screen, tab_id) if screen is not None else None
            if view is not None:
                reply(view)
                return True
        if main is None or tab_id not in dict(TABS):
            return False

        async def compose_then_reply() -> None:
            reply(await main.open_tab(tab_id))

        self.call_later(compose_then_reply)
        return True

    def main_screen(self) -> MainScreen | None:
        return next((s for s in self.screen_stack if isinstance(s, MainScreen)), None)

    def _config_reply(self, applied: dict[str, Any]) -> None:
        try:
            self.use_robot_config(daemon_robot_config(applied, self.robot_config))
        except (ConfigError, KeyError, TypeError, ValueError) as exc:
            self.local_event("refused", f"the daemon's config reply is unusable: {exc}")

    def use_robot_config(self, robot: RobotConfig) -> None:
        """Limits and names from now on: the composed tabs switch; the others are made with
        them when first shown (:meth:`make_tab`)."""
        self.robot_config = robot
        for screen in self.screen_stack:
            for tab in screen.query(TabView):
                if hasattr(tab, "robot"):
                    tab.robot = robot

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        # Halt and the lease are command verbs: an observer sees them greyed out.
        if action in ("halt", "lease") and not role_at_least(self, Role.OPERATOR):
            return None
        if action == "power" and not role_at_least(self, Role.ADMIN):
            return None
        return True

    def action_halt(self) -> None:
        self.link.halt()

    def action_power(self) -> None:
        # The daemon powers the servos only when they are off (the reset button), and gives
        # torque back only to those that had it; it answers `forbidden` to a non-admin.
        self.link.send("power", tag="app:power", op="on")

    def action_lease(self) -> None:
        holder = self.model.lease_holder()
        op = "release" if holder is not None and holder[1] else "acquire"
        self.link.send("lease", tag="app:lease", op=op)

    # -- the fleet (clients/tui/app_fleet.py) ----------------------------------------------------
    def action_next_robot(self) -> None:
        """Switch to the next live robot at the same endpoint (by name, wrapping round)."""
        finder, endpoint = self.find_robots, self.settings.endpoint
        if finder is None:
            self.notify(_("No robot list without a connection."), severity="warning")
            return

        def find() -> None:
            try:
                names = [r.name for r in finder(endpoint)]
            except Exception as exc:  # unreachable, or the session closed: say so
                self.call_from_thread(self.notify, str(exc), severity="error", timeout=8)
                return
            self.call_from_thread(self._switch_robot, names)

        self.run_worker(find, thread=True, exclusive=True, group="next-robot")

    def _switch_robot(self, names: list[str]) -> None:
        nxt = app_fleet.next_robot(names, self.settings.robot)
        if nxt is None:
            self.notify(
                _("No other live robot at {endpoint}.").format(endpoint=self.settings.endpoint)
            )
            return
        self.connect(Settings(self.settings.endpoint, nxt, self.settings.name, self.settings.lang))
        self.model.status = None  # the previous robot's state must not show as this one's
        self.model.bump("status")
        self.notify(_("Switched to {robot}.").format(robot=nxt))

    # -- telemetry (store only; the timer draws) -----------------------------------------------
    def on_telemetry_ready(self, _message: TelemetryReady) -> None:
        for topic, sample in self.link.inbox.take():
            self._store(topic, sample)

    def on_telemetry(self, message: Telemetry) -> None:
        self._store(message.topic, message.sample)

    def _store(self, topic: str, sample: Any) -> None:
        if topic == "camera" and not (self.link.watching_camera or not self._connect_on_mount):
            return  # a frame still in flight after the camera went out of view
        self.model.add(topic, sample)

    def on_version_notice(self, message: VersionNotice) -> None:
        self.notify(message.text, severity="warning", timeout=10)

    def on_link_changed(self, message: LinkChanged) -> None:
        info = message.info
        was = self.link_info.state
        self.link_info = info
        self.model.client_id = self.link.client_id or self.model.client_id
        self.model.bump("link")
        if info.state is LinkState.CONNECTED and was is not LinkState.CONNECTED:
            if self.screen_stack:  # (a link's news can come in while the app closes)
                self.screen.refresh_bindings()  # the role may grey some keys out
            if self.link.robot is not None:
                # What the tabs need once per connection (the library, the gait).
                # The daemon's joint limits, not this machine's config, bound what is sent.
                self.link.send("config", tag="app:config", quiet=True)
                self.link.send("behaviours", tag="app:library", quiet=True)
                if allows(self.link.role, "walk_params"):  # a read: observers may too
                    self.link.send("walk_params", tag="app:walk-params", quiet=True)
            self.local_event(
                "link",
                _("connected to {robot} at {endpoint}").format(
                    robot=info.robot, endpoint=info.endpoint
                ),
            )
            with contextlib.suppress(OSError):
                self.settings.save(self.settings_path)
        elif info.state in (LinkState.UNREACHABLE, LinkState.NO_DAEMON) and was != info.state:
            self.local_event("link", info.detail or _("daemon not running, waiting"))
        self.update_camera()

    def local_event(self, kind: str, text: str) -> None:
        """An event of this UI (link changes, refused commands) in the log."""
        self.model.add_event(Event(kind=kind, message=text, stamp=self.clock()))

    # -- drawing ---------------------------------------------------------------------------------
    def _changed(self, consumer: str, *streams: str) -> bool:
        version = self.model.version(*streams)
        if self._seen.get(consumer) == version:
            return False
        self._seen[consumer] = version
        return True

    def redraw(self, force: bool = False) -> None:
        if not self.screen_stack:
            return  # starting or shutting down: nothing to draw on
        screen: MainScreen | None = next(
            (s for s in (self.screen, *self.screen_stack) if isinstance(s, MainScreen)), None
        )
        if screen is None:
            return
        header = screen.query(RobotHeader)
        if not header:
            # Pushed but not composed yet (first show, or again after a language switch): the
            # timer can fire in between, and the screen's on_mount redraws everything anyway.
            return
        if self._changed("header", "status", "link") or force:
            header.first().update_view(self.model, self.link_info)
        tab = self.current_tab(screen)
        if tab is None or not tab.ready or not (tab.streaming or force):
            return
        if self._changed(f"tab-{tab.TAB_ID}", *tab.WATCHES) or force:
            tab.refresh_view(self.model)

    def current_tab(self, screen: Screen[Any] | None = None) -> TabView | None:
        if screen is None:
            if not self.screen_stack:
                return None  # starting, or closed its last screen: no tab shows
            screen = self.screen
        return tab_view(screen, self.active_tab)

    async def on_tabbed_content_tab_activated(self, event: TabbedContent.TabActivated) -> None:
        self.active_tab = (event.pane.id or "").removeprefix("pane-")
        screen = event.tabbed_content.screen
        if isinstance(screen, MainScreen) and self.active_tab in dict(TABS):
            # Composed here when its title was clicked (a number key composes it before it
            # shows); drawn below at once, as every tab is when shown, a new one too.
            tab: TabView | None = await screen.open_tab(self.active_tab)
        else:
            tab = self.current_tab()
        if tab is not None:
            self._seen.pop(f"tab-{tab.TAB_ID}", None)
            tab.refresh_view(self.model)
            self.call_after_refresh(tab.focus_target().focus)
        self.update_camera()

    def on_camera_tab_wanted(self, _message: CameraTab.Wanted) -> None:
        self.update_camera()

    def update_camera(self) -> None:
        """Follow the camera only while its tab shows with the stream on."""
        tab = self.current_tab()
        wanted = (
            isinstance(tab, CameraTab)
            and tab.streaming
            and self.link_info.state is LinkState.CONNECTED
        )
        self.link.watch_camera(wanted)

    # -- screens and settings --------------------------------------------------------------------
    def action_connect(self) -> None:
        detail = self.link_info.detail if self.link_info.state is LinkState.UNREACHABLE else ""

        def done(result: Settings | None) -> None:
            if result is not None:
                self.connect(result)

        self.push_screen(ConnectScreen(self.settings, detail, self.find_robots), done)

    def action_help(self) -> None:
        if isinstance(self.screen, HelpScreen):
            return
        sections: list[tuple[str, list[Any]]] = [(_("Everywhere"), list(self.BINDINGS))]
        tab = self.current_tab()
        if tab is not None:
            title = dict(TABS)[tab.TAB_ID]
            sections.insert(0, (_("This tab: {name}").format(name=_(title)), list(tab.BINDINGS)))
        self.push_screen(HelpScreen(sections))

    async def action_language(self) -> None:
        langs = i18n.available()
        nxt = langs[(langs.index(i18n.language()) + 1) % len(langs)]
        await self.set_language(nxt)

    async def set_language(self, lang: str) -> None:
        self.settings.lang = i18n.set_language(lang)
        with contextlib.suppress(OSError):
            self.settings.save(self.settings_path)
        main = self.main_screen()
        if main is not None:
            await main.recompose()
            self._seen.clear()
            self.redraw(force=True)
            tab = self.current_tab(main)
            if tab is not None:
                tab.focus_target().focus()

    async def action_show_tab(self, tab_id: str) -> None:
        main = self.main_screen()
        if main is None:
            return
        # Composed before it shows, so no frame of an empty pane; and the key's handling ends
        # with the tab ready for the next key.
        await main.open_tab(tab_id)
        main.query_one(TabbedContent).active = f"pane-{tab_id}"

    # -- recording (Log tab) ---------------------------------------------------------------------
    def on_log_tab_record(self, message: LogTab.Record) -> None:
        tab = message.control if isinstance(message.control, LogTab) else None
        if message.path is None:
            summary = self.stop_recording()
            if tab is not None:
                tab.set_recording(False, summary)
            return
        if self.link.robot is None:
            self.notify(_("Connect to a robot before recording."), severity="error")
            return
        from clients.recording import Recorder  # only when asked: mcap is a heavy import

        try:
            self._recorder = Recorder(
                self.link.robot,
                message.path,
                split_seconds=message.split_seconds,
                split_bytes=message.split_bytes,
                profile=message.profile,
                on_notice=lambda line: self.notify(line, severity="warning", timeout=12),
            ).start()
        except (OSError, ValueError, ClientError) as exc:
            self.notify(str(exc), severity="error", timeout=12)
            return
        segments = self._recorder.stats.segments
        self.recording_to = where = f"{segments[0]} …" if segments else message.path
        self.local_event("record", _("recording to {path}").format(path=where))
        if tab is not None:
            tab.set_recording(True, _("recording to {path}").format(path=where))

    def stop_recording(self) -> str:
        if self._recorder is None:
            return ""
        recorder, self._recorder = self._recorder, None
        self.recording_to = None
        summary = recorder.stop().summary()
        self.local_event("record", summary)
        return summary
