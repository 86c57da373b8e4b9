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


SEP = "  "


def fit(fields: list[Text], width: int, short: dict[int, Text] | None = None) -> Text:
    """One line of whole fields, two spaces apart, as many as fit in ``width`` cells: a field
    is shown entire (or in its ``short`` form) or not at all, so two fields never run into
    each other."""
    line = Text(no_wrap=True, overflow="ellipsis", end="")
    for i, f in enumerate(fields):
        gap = len(SEP) if i else 0
        if line.cell_len + gap + f.cell_len > width and short and i in short:
            f = short[i]
        if line.cell_len + gap + f.cell_len > width:
            if i == 0:  # even the first does not fit: it is cut, visibly
                line.append_text(f)
                line.truncate(width, overflow="ellipsis")
            break
        if gap:
            line.append(SEP)
        line.append_text(f)
    return line


def _field(*parts: tuple[str, str]) -> Text:
    out = Text(no_wrap=True, end="")
    for words, style in parts:
        out.append(words, style=style)
    return out


class RobotHeader(Static):
    DEFAULT_CSS = """
    RobotHeader { dock: top; height: 2; background: $panel; padding: 0 1; }
    """

    _last: tuple[Model, LinkInfo] | None = None

    def update_view(self, model: Model, info: LinkInfo) -> None:
        self._last = (model, info)
        self.refresh()

    def render(self) -> Text:
        # Composed at drawing time, for the width the header has then (resizes included).
        if self._last is None:
            return Text("")
        return self.compose_text(*self._last, self.content_size.width or None)

    @staticmethod
    def compose_text(model: Model, info: LinkInfo, width: int | None = None) -> Text:
        """The header's two lines, each cut to ``width`` cells by whole fields."""
        top, bottom = RobotHeader.fields(model, info)
        limit = width if width and width > 0 else 10_000
        short = RobotHeader.short_fields(model, info, len(bottom))
        return Text("\n").join([fit(top, limit), fit(bottom, limit, short)])

    @staticmethod
    def short_fields(model: Model, info: LinkInfo, count: int) -> dict[int, Text]:
        """Shorter forms of bottom fields, by index: the alarm count without its detail."""
        st = model.status
        if st is None or not st.alarms or info.state is not LinkState.CONNECTED:
            return {}
        return {count - 1: _field((_("alarms") + ": ", "dim"), (str(len(st.alarms)), "bold red"))}

    @staticmethod
    def fields(model: Model, info: LinkInfo) -> tuple[list[Text], list[Text]]:
        words, style = link_text(info)
        # Most important first: a narrow terminal drops fields from the end.
        top = [
            _field(("DARwIn-OP ", "bold"), (info.robot or "—", "bold cyan")),
            _field(("● ", style), (words, style)),
        ]
        st = model.status
        if st is not None and info.state is LinkState.CONNECTED:
            top.append(_field((f"[{st.state}]", "yellow" if st.state != "running" else "dim")))
        top.append(_field((f"@ {info.endpoint or '—'}", "dim")))
        if info.state in (LinkState.UNREACHABLE, LinkState.NO_DAEMON):
            hint = _("Is `darwin up` running there? Press c to change the robot.")
            if "protocol" in info.detail:  # an incompatible daemon: say which and what to do
                hint = info.detail
            return top, [_field((hint, "red"))]
        bottom = []
        holder = model.lease_holder()
        if holder is None:
            who = (_("free"), "green")
        elif holder[1]:
            who = (_("you"), "bold reverse green")
        else:
            who = (_("held by {name}").format(name=holder[0]), "bold yellow")
        bottom.append(_field((_("lease") + ": ", "dim"), who))
        loop = model.loop_rate()
        if loop is not None:
            hz, overruns = loop
            bottom.append(_field((_("loop") + ": ", "dim"), (f"{hz:.0f} Hz", "")))
            bottom.append(_field((_("overruns") + f" {overruns}", "red" if overruns else "dim")))
            overloaded = model.loop_overloaded()
            if overloaded is not None:
                text = _("OVERLOADED {pct:.0f} %").format(pct=overloaded)
                bottom.append(_field((text, "bold reverse red")))
        if st is not None:
            volts = (f"{st.voltage:.1f} V", "red" if st.voltage < LOW_BATTERY_V else "")
            bottom.append(_field((_("battery") + ": ", "dim"), volts))
            # The battery and heat policy (docs/power.md): shown once it is past ok.
            level = (st.power or {}).get("level", "ok")
            if level != "ok":
                bottom.append(_field((level, "bold red" if level != "warn" else "bold yellow")))
            heat = st.heat or {}
            if heat.get("level", "ok") != "ok" and heat.get("hottest"):
                hot = heat["hottest"][0]
                text = f"{hot['name']} {hot['celsius']:.0f} °C {heat['level']}"
                bottom.append(_field((_("hottest") + ": ", "dim"), (text, "bold red")))
            if st.alarms:
                first = st.alarms[0]
                what = first.get("message") or first.get("kind") or str(first)
                alarms = (f"{len(st.alarms)} ({what})", "bold red")
            else:
                alarms = (_("none"), "green")
            bottom.append(_field((_("alarms") + ": ", "dim"), alarms))
        return top, bottom
