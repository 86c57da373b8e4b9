"""Vision in the daemon: camera sources (``sources.py``) and the ball finder."""
