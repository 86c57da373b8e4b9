"""``darwin web``: the terminal UI served to web browsers (textual-serve)."""
