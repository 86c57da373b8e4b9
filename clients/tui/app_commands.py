"""The TUI app's commands: what it sends for the tabs and itself, where each reply goes, what
the app does with its own replies (the daemon's config, the behaviour library, the gait, halt,
the lease). Mixed into :class:`clients.tui.app.DarwinApp`.
"""

from __future__ import annotations

from typing import Any

from clients.tui.i18n import _
from clients.tui.link import CommandDone, Link
from clients.tui.model import Model
from clients.tui.tabs.base import SendCommand, TabView, role_at_least
from clients.tui.tabs.behaviours import library_entries
from config.loader import RobotConfig, robot_from_dict
from schemas.errors import ConfigError
from schemas.roles import Role


class CommandsMixin:
    """Needs what :class:`DarwinApp` has: the link, the model, the robot config, ``local_event``
    and Textual's ``App`` (``screen``, ``screen_stack``, ``notify``)."""

    link: Link
    model: Model
    robot_config: RobotConfig
    screen: Any
    screen_stack: Any
    notify: Any
    local_event: Any

    def on_send_command(self, message: SendCommand) -> None:
        origin = message.control.TAB_ID if isinstance(message.control, TabView) else "app"
        self.link.send(
            message.verb, tag=f"{origin}:{message.tag}", quiet=message.quiet, **message.fields
        )

    def on_command_done(self, message: CommandDone) -> None:
        origin, _sep, tag = message.tag.partition(":")
        if message.error:
            self.local_event("refused", message.error)
        if origin == "app":
            self.app_command_done(tag, message)
            return
        tabs = self.screen.query(f"#{origin}") if origin else None
        if tabs:
            tabs.first(TabView).command_done(tag, message.applied, message.error)
        elif message.error:
            self.notify(message.error, severity="error", timeout=6)

    def app_command_done(self, tag: str, message: CommandDone) -> None:
        if message.error:
            self.notify(message.error, severity="error", timeout=6)
        elif tag == "config":
            try:
                self.use_robot_config(daemon_robot_config(message.applied, self.robot_config))
            except (ConfigError, KeyError, TypeError, ValueError) as exc:
                self.local_event("refused", f"the daemon's config reply is unusable: {exc}")
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
            self.notify(_("Lease: {state}").format(state=holds or message.applied or "ok"))

    def use_robot_config(self, robot: RobotConfig) -> None:
        """Limits and names from now on; the open tabs switch too."""
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
