"""The header every screen shows: robot, link, lease, loop rate and overruns, battery, alarms."""

from __future__ import annotations

from rich.text import Text
from textual.widgets import Static

from clients.tui.i18n import _
from clients.tui.messages import LinkInfo, LinkState
from clients.tui.model import Model

LOW_BATTERY_V = 11.0


def link_text(info: LinkInfo) -> tuple[str, str]:
    """``(words, style)`` for a link state."""
    return {
        LinkState.IDLE: (_("not connected"), "dim"),
        LinkState.CONNECTING: (_("connecting…"), "yellow"),
        LinkState.UNREACHABLE: (_("unreachable, retrying"), "bold red"),
        LinkState.NO_DAEMON: (_("daemon not running, waiting"), "bold red"),
        LinkState.CONNECTED: (_("connected"), "bold green"),
    }[info.state]


class RobotHeader(Static):
    DEFAULT_CSS = """
    RobotHeader { dock: top; height: 2; background: $panel; padding: 0 1; }
    """

    def update_view(self, model: Model, info: LinkInfo) -> None:
        self.update(self.compose_text(model, info))

    @staticmethod
    def compose_text(model: Model, info: LinkInfo) -> Text:
        words, style = link_text(info)
        top = Text(no_wrap=True, overflow="ellipsis")
        top.append("DARwIn-OP ", style="bold")
        top.append(info.robot or "—", style="bold cyan")
        top.append(f" @ {info.endpoint or '—'}  ", style="dim")
        top.append("● ", style=style)
        top.append(words, style=style)
        st = model.status
        if st is not None and info.state is LinkState.CONNECTED:
            top.append(f"  [{st.state}]", style="yellow" if st.state != "running" else "dim")
        bottom = Text(no_wrap=True, overflow="ellipsis")
        if info.state in (LinkState.UNREACHABLE, LinkState.NO_DAEMON):
            hint = _("Is `darwin up` running there? Press c to change the robot.")
            bottom.append(hint, style="red")
            return Text("\n").join([top, bottom])
        holder = model.lease_holder()
        bottom.append(_("lease") + ": ", style="dim")
        if holder is None:
            bottom.append(_("free"), style="green")
        elif holder[1]:
            bottom.append(_("you"), style="bold reverse green")
        else:
            bottom.append(_("held by {name}").format(name=holder[0]), style="bold yellow")
        loop = model.loop_rate()
        if loop is not None:
            hz, overruns = loop
            bottom.append("  " + _("loop") + ": ", style="dim")
            bottom.append(f"{hz:.0f} Hz")
            bottom.append("  " + _("overruns") + f" {overruns}", style="red" if overruns else "dim")
        if st is not None:
            bottom.append("  " + _("battery") + ": ", style="dim")
            bottom.append(f"{st.voltage:.1f} V", style="red" if st.voltage < LOW_BATTERY_V else "")
            bottom.append("  " + _("alarms") + ": ", style="dim")
            if st.alarms:
                first = st.alarms[0]
                what = first.get("message") or first.get("kind") or str(first)
                bottom.append(f"{len(st.alarms)} ({what})", style="bold red")
            else:
                bottom.append(_("none"), style="green")
        return Text("\n").join([top, bottom])
