"""``darwin tui``: the Textual terminal UI. Build it with :class:`clients.tui.app.DarwinApp`."""
