"""Where the Foxglove server gets the robot's URDF: one provider, one place."""

from __future__ import annotations

import importlib


def robot_description() -> str | None:
    """The robot's URDF text, or None when this build has no body description.

    LEAD: point this at schemas/body.py's URDF function when merging (the single body
    description); until then it looks for it by name and the server does not advertise the
    URDF channel when it is absent. Never write a URDF here.
    """
    try:
        body = importlib.import_module("schemas.body")
    except ModuleNotFoundError:
        return None
    for name in ("urdf", "robot_urdf", "urdf_text", "generate_urdf"):
        fn = getattr(body, name, None)
        if callable(fn):
            text = fn()
            return text if isinstance(text, str) and text.strip() else None
    return None
