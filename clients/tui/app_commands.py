"""The TUI's commands: what it sends for the tabs and itself, and where each reply goes (the
tab that sent it, or the app's own: the daemon's config, the behaviour library, the gait, halt,
the lease). The app has one :class:`CommandRouter`, made with only what it uses.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from clients.tui.i18n import _
from clients.tui.link import CommandDone, Link
from clients.tui.model import Model
from clients.tui.tabs.base import SendCommand, TabView
from clients.tui.tabs.behaviours import library_entries
from config.loader import RobotConfig, robot_from_dict

Notify = Callable[..., None]  # App.notify(message, severity=…, timeout=…)
# (tab id, what to do with its view) → False when no such tab is there to take a reply
ToTab = Callable[[str, Callable[[TabView], None]], bool]


class CommandRouter:
    def __init__(
        self,
        link: Link,
        model: Model,
        notify: Notify,
        local_event: Callable[[str, str], None],
        config_reply: Callable[[dict[str, Any]], None],
    ) -> None:
        self.link = link
        self.model = model
        self.notify = notify
        self.local_event = local_event  # a line in the log tab (kind, text)
        self.config_reply = config_reply  # the daemon's `config` reply, for the app to use

    def send(self, message: SendCommand) -> None:
        origin = message.control.TAB_ID if isinstance(message.control, TabView) else "app"
        self.link.send(
            message.verb, tag=f"{origin}:{message.tag}", quiet=message.quiet, **message.fields
        )

    def done(self, message: CommandDone, to_tab: ToTab) -> None:
        """A reply: to the tab that sent the command (``to_tab`` finds it), or the app's own."""
        origin, _sep, tag = message.tag.partition(":")
        if message.error:
            self.local_event("refused", message.error)
        if origin == "app":
            self._app_done(tag, message)
            return

        def reply(tab: TabView) -> None:
            tab.command_done(tag, message.applied, message.error)

        if not (origin and to_tab(origin, reply)) and message.error:
            self.notify(message.error, severity="error", timeout=6)

    def _app_done(self, tag: str, message: CommandDone) -> None:
        if message.error:
            self.notify(message.error, severity="error", timeout=6)
        elif tag == "config":
            self.config_reply(message.applied)
        elif tag == "library":
            self.model.edits.behaviours = library_entries(message.applied)
            self.model.bump("library")
        elif tag == "walk-params":
            params = message.applied.get("params", message.applied)
            if isinstance(params, dict):
                self.model.edits.walk_params = dict(params)
                self.model.bump("params")
        elif tag == "halt":
            self.model.edits.walk = (0.0, 0.0, 0.0)
            self.local_event("halt", _("Halted: every motion stopped, the pose is held."))
            self.notify(_("Halted: every motion stopped, the pose is held."), timeout=4)
        elif tag == "power":
            done = _("Servos powered again.") if message.applied.get("changed") else _(
                "The servos are already powered."
            )
            self.notify(done, timeout=4)
        elif tag == "lease":
            holds = message.applied.get("holder", message.applied.get("client"))
            if isinstance(holds, dict):  # the holder as the daemon describes it
                holds = holds.get("name") or holds.get("client")
            self.notify(_("Lease: {state}").format(state=holds or _("free")))


def daemon_robot_config(reply: dict[str, Any], local: RobotConfig) -> RobotConfig:
    """The robot as the daemon's ``config`` verb describes it (its limits are the ones that
    count), in the same checked form as a config file; ``local`` where the reply is silent."""
    section = {
        "name": reply.get("robot", local.name),
        "cm730_id": local.cm730_id,
        "defaults": {"max_speed": reply.get("max_speed", local.max_speed)},
        "joints": {
            j["name"]: {
                "id": j["id"],
                "urdf": j.get("urdf", j["name"]),
                "min_deg": j["min_deg"],
                "max_deg": j["max_deg"],
                "offset_deg": j.get("offset_deg", 0.0),
                "direction": j.get("direction", 1),
                **dict(zip(("p", "i", "d"), j.get("pid", (32, 0, 0)), strict=False)),
            }
            for j in reply.get("joints", [])
        },
    }
    return robot_from_dict(section) if section["joints"] else local
