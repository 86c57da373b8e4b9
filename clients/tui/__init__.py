"""``darwin tui``: the Textual terminal UI. Build it with :func:`clients.tui.app.create_app`."""
