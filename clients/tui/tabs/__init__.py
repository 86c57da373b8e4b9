"""The tabs of the main screen, one module each (widget, bindings, CSS)."""
