"""The app on a fixed scene through Pilot: no robot, messages fed directly."""

from __future__ import annotations

import gc
import json
import math
from pathlib import Path

from textual import events
from textual.widgets import DataTable, Label, OptionList, RichLog, TabbedContent

from clients.tui.app import DarwinApp
from clients.tui.help import HelpScreen
from clients.tui.link import CommandDone
from clients.tui.messages import LinkChanged, LinkInfo, LinkState, Telemetry
from clients.tui.tabs.actions import ActionsTab
from clients.tui.tabs.base import TabView
from clients.tui.tabs.behaviours import BehavioursTab
from clients.tui.widgets.figure import StickFigure
from clients.tui.widgets.header import RobotHeader
from schemas.messages import Event
from tests.ui import scene
from tests.ui.live import show_tab, until


def header_text(app) -> str:
    return str(app.screen.query_one(RobotHeader).render())


async def test_header_shows_lease_loop_battery_and_alarms(scene_app) -> None:
    app = scene_app()
    async with app.run_test(size=(120, 30)) as pilot:
        await pilot.pause(0.2)
        text = header_text(app)
        assert "connected" in text and "op1" in text
        assert "you" in text and "125 Hz" in text and "overruns 2" in text
        assert "12.1 V" in text and "r_hip_roll overheating" in text
        app.post_message(Telemetry("joints", scene.joints()))  # keeps the scene alive
        app.model.add_status(scene.status(lease_client="someone-else"))
        await pilot.pause(0.2)
        assert "held by tui" in header_text(app)
        assert "OVERLOADED" not in header_text(app)
        overloaded = scene.status()
        overloaded.loop = {**overloaded.loop, "overloaded": True, "overrun_pct": 37.0}
        app.model.add_status(overloaded)
        await pilot.pause(0.2)
        assert "OVERLOADED 37 %" in header_text(app)


async def test_unreachable_robot_is_explained(scene_app) -> None:
    app = scene_app()
    async with app.run_test(size=(100, 30)) as pilot:
        info = LinkInfo(LinkState.UNREACHABLE, "tcp/10.9.9.9:7447", "op1", "no route")
        app.post_message(LinkChanged(info))
        await pilot.pause(0.2)
        text = header_text(app)
        assert "unreachable" in text and "darwin up" in text


async def test_motor_table_updates_in_place_keeping_the_selection(scene_app) -> None:
    app = scene_app(tab="motors")
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause(0.2)
        table = app.screen.query_one("#joint-table", DataTable)
        assert app.focused is table
        await pilot.press("down", "down", "down", "down")
        assert table.cursor_row == 4
        joints = scene.joints(tick=999)
        joints.position[4] = math.radians(42.5)  # the wire's radians, shown in degrees
        app.post_message(Telemetry("joints", joints))
        await pilot.pause(0.3)
        assert table.get_cell("5", "pos").strip() == "42.5"
        assert table.cursor_row == 4 and app.focused is table
        assert table.get_cell("17", "online") == "✗"  # the scene's offline servo
        assert table.get_cell("9", "alarm") == "0x20"


async def test_commands_without_a_robot_say_so_in_the_log(scene_app) -> None:
    app = scene_app(tab="motors")
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause(0.2)
        before = app.model.event_count
        await pilot.press("right_square_bracket")
        await until(
            pilot,
            lambda: any("not connected" in e.message for e in app.model.events_since(before)),
            "the refusal in the log",
        )
        assert app.model.event_count == before + 1  # no robot: nothing else is logged


async def test_a_starved_app_takes_every_waiting_sample_with_one_message(scene_app) -> None:
    """Joints and IMU interleave at 125 Hz each: one message per sample backed the app up for
    good once it was starved (keys queued behind the backlog). However many samples wait, one
    TelemetryReady is queued, and taking it stores them all, every event too."""
    import threading

    from clients.tui.messages import TelemetryReady

    app = scene_app()
    async with app.run_test(size=(120, 30)) as pilot:
        await pilot.pause(0.1)
        joints_before, events_before = len(app.model.joint_hist), app.model.event_count
        n = 500

        def zenoh_thread() -> None:  # the link's callbacks, on a thread of their own
            for k in range(n):
                app.link.inbox.put("joints", scene.joints(tick=k, stamp=scene.T0 + k * 0.008))
                app.link.inbox.put("imu", scene.imu(k))
                if k % 50 == 0:
                    app.link.inbox.put("events", Event(kind="lease", message=f"e{k}"))

        # The app's thread is held (as a starved one is) while the samples arrive.
        posted: list[object] = []
        post = app.post_message
        app.post_message = lambda m: posted.append(m) or post(m)  # type: ignore[method-assign]
        thread = threading.Thread(target=zenoh_thread)
        thread.start()
        thread.join()
        app.post_message = post  # type: ignore[method-assign]
        assert [type(m) for m in posted] == [TelemetryReady]
        await until(pilot, lambda: len(app.model.joint_hist) - joints_before == n, "every sample")
        assert app.model.event_count - events_before == n // 50
        assert [e.message for e in app.model.events][-2:] == ["e400", "e450"]


async def test_telemetry_messages_replace_older_queued_ones() -> None:
    a, b = Telemetry("imu", scene.imu(1)), Telemetry("imu", scene.imu(2))
    assert b.can_replace(a)
    assert not b.can_replace(Telemetry("joints", scene.joints()))
    # each event is a line of the log: a newer one never drops a queued older one
    first, second = (Telemetry("events", Event(kind="lease", message=m)) for m in "ab")
    assert not second.can_replace(first)


async def test_language_switch_translates_tabs_and_keeps_edits(scene_app) -> None:
    app = scene_app(tab="behaviours")
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause(0.2)
        labels = [str(t.label) for t in app.screen.query("ContentTab")]
        assert "2 Motors" in labels
        await pilot.press("f2")
        await pilot.pause(0.3)
        labels = [str(t.label) for t in app.screen.query("ContentTab")]
        assert "2 Motores" in labels and "6 Comportamentos" in labels
        assert "liberar" in str(app.screen.query_one("KeyBar").render())
        assert len(app.model.edits.choreography) == 3
        assert app.screen.query_one(TabbedContent).active == "pane-behaviours"
        assert app.settings.lang == "pt"
        await pilot.press("f2")
        await pilot.pause(0.3)
        labels = [str(t.label) for t in app.screen.query("ContentTab")]
        assert "2 Motors" in labels


async def test_the_events_panel_shows_the_log_after_a_language_switch_without_a_resize(
    scene_app, monkeypatch
) -> None:
    # The Log tab's RichLog holds every write until a Resize event gives it a width. In tmux
    # on a loaded machine, after F2 composed the screen again, that event never reached it
    # (laid out at 78x16, its writes still held): the Events panel stayed empty for good,
    # 'halt' and every later event included. The same, made certain: it gets no Resize. The
    # Log tab is composed when first shown, after the switch: deaf from its making.
    from clients.tui.tabs import log as log_tab

    class DeafEventsLog(log_tab.EventsLog):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            self.disable_messages(events.Resize)

    monkeypatch.setattr(log_tab, "EventsLog", DeafEventsLog)
    app = scene_app(tab="motors")
    async with app.run_test(size=(100, 30)) as pilot:
        await until(pilot, lambda: app.model.event_count > 0, "the scene's events")
        await pilot.press("f2")
        await until(pilot, lambda: app.settings.lang == "pt", "the language switch")
        await pilot.press("7")
        log = app.screen.query_one("#events", RichLog)
        assert isinstance(log, DeafEventsLog)
        app.post_message(Telemetry("events", Event(kind="halt", message="halt by 'ssh-user'")))

        def shown() -> str:
            return "\n".join(strip.text for strip in log.lines)

        await until(pilot, lambda: "halt by 'ssh-user'" in shown(), "the halt in the panel")
        assert "the robot fell forward" in shown()  # the events from before the switch too


async def test_a_tab_is_composed_when_first_shown_drawn_at_once_and_kept(
    scene_app, monkeypatch
) -> None:
    # Only the tab that shows is composed at start: every other one cost each start CPU, for
    # a view the session may never open. A tab shown later draws the model as it is then, at
    # once: the render timer draws nothing in this test, and the Actions tab's mount does not
    # draw its status line. A tab left keeps its state.
    monkeypatch.setattr(DarwinApp, "redraw", lambda self, force=False: None)
    app = scene_app(tab="motors")
    async with app.run_test(size=(120, 40)) as pilot:
        await until(pilot, lambda: app.model.status is not None, "the scene")
        assert [t.TAB_ID for t in app.screen.query(TabView)] == ["motors"]
        motors = app.current_tab()
        table = app.screen.query_one("#joint-table", DataTable)
        await until(pilot, lambda: app.focused is table, "the focus in the joint table")
        await pilot.press("down", "down", "down", "down", "a")  # joint 5, plotted as A
        assert table.cursor_row == 4 and motors.plotted["a"] == 5
        # The robot plays a page while the Actions tab was never composed.
        playing = scene.status()
        playing.motion = {**playing.motion, "action": {"playing": True, "page": 4, "step": 2}}
        app.model.add_status(playing)
        await show_tab(pilot, 8)
        actions = app.current_tab()
        assert isinstance(actions, ActionsTab)
        status = str(actions.query_one("#actions-status", Label).content)
        assert "playing page 4 step 2" in status
        await show_tab(pilot, 2)
        assert app.current_tab() is motors  # the view itself, not one composed again
        assert table.cursor_row == 4 and motors.plotted["a"] == 5
        assert sorted(t.TAB_ID for t in app.screen.query(TabView)) == ["actions", "motors"]


async def test_a_reply_reaches_its_tab_after_the_screen_was_composed_again(scene_app) -> None:
    # F2 composes the screen again, with only the tab that shows. A reply to a command another
    # tab sent before (here the Actions tab's page list) is not lost: that tab is composed for
    # it, under a dialog too, and shows it when shown.
    app = scene_app(tab="actions")
    async with app.run_test(size=(120, 36)) as pilot:
        # The tab asks for the list once connected; with no robot the answer is a refusal,
        # which must have come before the reply this test sends.
        st = app.model.edits
        await until(pilot, lambda: st.actions is not None and st.actions.requested, "the ask")
        await until(pilot, lambda: any(e.kind == "refused" for e in app.model.events), "refused")
        await show_tab(pilot, 1)
        await pilot.press("f2")
        await until(pilot, lambda: app.settings.lang == "pt", "the language switch")
        assert [t.TAB_ID for t in app.screen.query(TabView)] == ["imu"]
        await pilot.press("f1")
        await until(pilot, lambda: isinstance(app.screen, HelpScreen), "the help")
        pages = [{"number": 4, "name": "wave", "steps": 6, "repeat": 1, "speed": 32,
                  "next": 0, "exit": 0, "origin": "shipped"}]  # fmt: skip
        app.post_message(CommandDone("pages", "actions:list", {"pages": pages}))
        await until(pilot, lambda: st.actions.listing == pages, "the page list")
        await pilot.press("escape")
        await show_tab(pilot, 8)
        listing = app.screen.query_one("#pages-list", DataTable)
        assert listing.row_count == 1 and listing.get_cell("4", "name") == "wave"


async def test_choreography_add_reorder_remove_save_load(scene_app, tmp_path: Path) -> None:
    app = scene_app(tab="behaviours")
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause(0.2)
        tab = app.screen.query_one(BehavioursTab)
        library = app.screen.query_one("#library", OptionList)
        assert library.option_count == len(scene.LIBRARY)
        library.focus()
        await pilot.press("down", "down", "enter")  # walk forward
        items = app.model.edits.choreography
        assert [i["behaviour"] for i in items] == ["stand", "walk_fwd", "bow", "walk_fwd"]
        chor = app.screen.query_one("#choreography", OptionList)
        chor.focus()
        chor.highlighted = 3
        await pilot.press("shift+up")
        assert [i["behaviour"] for i in items] == ["stand", "walk_fwd", "walk_fwd", "bow"]
        await pilot.press("plus")
        assert items[2]["duration"] == 3.5
        await pilot.press("delete")
        assert [i["behaviour"] for i in app.model.edits.choreography] == [
            "stand",
            "walk_fwd",
            "bow",
        ]
        path = tmp_path / "dance.json"
        app.screen.query_one("#chor-file").value = str(path)
        tab.action_save()
        saved = json.loads(path.read_text())
        assert saved["items"][1] == {"behaviour": "walk_fwd", "duration": 3.0, "x": 0.04}
        app.model.edits.choreography.clear()
        tab.action_load()
        assert len(app.model.edits.choreography) == 3
        path.write_text("{not json")
        tab.action_load()
        assert len(app.model.edits.choreography) == 3  # a bad file changes nothing


async def test_pose_manipulate_simulate_reset(scene_app) -> None:
    app = scene_app(tab="pose")
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause(0.2)
        figure = app.screen.query_one(StickFigure)
        assert figure.border_title == "robot (live)"
        await pilot.press("m")
        edits = app.model.edits
        assert edits.manipulate and len(edits.pose) == 20
        before = edits.pose[1]
        await pilot.press("right_square_bracket", "right_square_bracket")
        assert abs(edits.pose[1] - before - 0.1745) < 1e-3
        await pilot.press("s")
        assert figure.border_title == "simulated pose (not sent)"
        await pilot.press("z")
        assert edits.pose[1] == before and figure.border_title == "robot (live)"


async def test_help_lists_the_keys_of_the_tab_and_of_the_app(scene_app) -> None:
    app = scene_app(tab="walk")
    async with app.run_test(size=(100, 40)) as pilot:
        await pilot.pause(0.1)
        await pilot.press("f1")
        await pilot.pause(0.1)
        assert isinstance(app.screen, HelpScreen)
        titles = [title for title, _b in app.screen.sections]
        assert titles == ["This tab: Walk", "Everywhere"]
        await pilot.press("escape")
        assert not isinstance(app.screen, HelpScreen)


async def test_imu_series_toggle_and_zoom(scene_app) -> None:
    app = scene_app(tab="imu")
    async with app.run_test(size=(100, 30)) as pilot:
        await pilot.pause(0.2)
        plot = app.screen.query_one("#accel-plot")
        assert [s.visible for s in plot._series] == [True, True, True]
        await pilot.press("y")
        await pilot.pause(0.1)
        assert [s.visible for s in plot._series] == [True, False, True]
        await pilot.press("minus")
        assert plot.window_s == 10.0


async def test_header_fields_stay_apart_at_every_width(scene_app) -> None:
    for width in (30, 45, 60, 75, 90, 120):
        app = scene_app()
        async with app.run_test(size=(width, 30)) as pilot:
            await pilot.pause(0.2)
            header = app.screen.query_one(RobotHeader)
            top, bottom = RobotHeader.fields(app.model, app.link_info)
            short = RobotHeader.short_fields(app.model, app.link_info, len(bottom))
            for y, fields in enumerate((top, bottom)):
                line = "".join(seg.text for seg in header.render_line(y)).strip()
                shown = line.split("  ")
                # Every piece is one whole field (or its short form), in order, none cut or
                # run into another.
                for i, piece in enumerate(shown):
                    forms = {fields[i].plain} | ({short[i].plain} if y and i in short else set())
                    assert piece in forms, (width, line)
                assert len(line) <= width
            assert "connected" in "".join(seg.text for seg in header.render_line(0))


async def test_pose_limits_come_from_the_daemon_not_the_local_config(scene_app) -> None:
    from clients.tui.link import CommandDone
    from clients.tui.tabs.pose import PoseTab
    from config.loader import load_all
    from robot_daemon.arbiter.registry import Request
    from robot_daemon.arbiter.verbs.basic import config
    from tests.fixtures.motion import motion_context

    # The daemon runs with a narrower head pan than this machine's config says.
    settings = load_all()
    settings["robot"]["joints"]["head_pan"]["max_deg"] = 20.0
    ctx = motion_context(settings)
    reply = config(Request("config", "c", "t", {}), ctx)
    app = scene_app(tab="pose")
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause(0.2)
        assert app.robot_config.joint("head_pan").max_deg > 20.0
        app.post_message(CommandDone("config", "app:config", reply))
        await pilot.pause(0.2)
        assert app.robot_config.joint("head_pan").max_deg == 20.0
        await pilot.press("m")
        pose = app.screen.query_one(PoseTab)
        jid = app.robot_config.joint("head_pan").id
        pose.set_edit(jid, 45.0)
        assert abs(app.model.edits.pose[jid] - math.radians(20.0)) < 1e-9


async def test_full_collections_walk_only_what_the_running_app_allocated(scene_app) -> None:
    # Once built, the app takes what is alive out of full collections (a full collection holds
    # the interpreter, and with it the lease renewals, for as long as it walks the heap), and
    # gives it back when it ends, so a process that goes on does not keep the app's garbage.
    gc.unfreeze()  # whatever an earlier test of this process left
    app = scene_app()
    async with app.run_test(size=(120, 30)) as pilot:
        await until(pilot, lambda: gc.get_freeze_count() > 0, "the heap frozen after start")
        alive_at_start = gc.get_freeze_count()
        assert alive_at_start > len(gc.get_objects())  # the young heap is the smaller part
    assert gc.get_freeze_count() == 0


def test_a_reply_that_comes_in_while_the_app_closes_is_dropped(scene_app) -> None:
    # The link's thread posts a command's outcome whenever it comes; on a loaded machine one
    # came in after the app had closed its last screen, and reading `app.screen` then raised
    # ScreenStackError out of the app (test_versions_power failed so).
    from clients.tui.link import CommandDone

    app = scene_app()
    assert not app.screen_stack  # not running: no screen at all, as after the last is closed
    app.on_command_done(CommandDone("config", "app:config", {}))


def test_link_news_that_comes_in_while_the_app_closes_is_kept_and_draws_nothing(
    scene_app,
) -> None:
    # The same for the link's news: a "still connected" posted as the app closed its last
    # screen reached `app.screen` through the camera's follow (test_versions_power failed so on
    # a quiet machine); a first "connected" would through the key bar's refresh.
    app = scene_app()
    assert not app.screen_stack
    for was in (LinkState.CONNECTED, LinkState.UNREACHABLE):
        app.link_info = LinkInfo(was, "tcp/127.0.0.1:7447", "darwin")
        app.on_link_changed(LinkChanged(LinkInfo(LinkState.CONNECTED, "tcp/127.0.0.1:7447", "x")))
        assert app.link_info.robot == "x"  # what the link said is kept for the header
    assert app.current_tab() is None
