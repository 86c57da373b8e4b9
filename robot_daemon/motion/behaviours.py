"""The behaviour library (``config/behaviours.toml``) and the items a choreography plays.

A behaviour has an id, an English and a Portuguese name, a kind and parameters. A choreography
item names a behaviour and may override its parameters (SI units on the wire: m/s, rad/s, rad,
s), or gives a kind and its parameters directly:

    {"behaviour": 100, "duration": 5.0}          walk forward for 5 s
    {"behaviour": "wow"}                         by name (English or Portuguese)
    {"kind": "led", "eye": [0, 255, 0]}
    {"page": 15}                                 an action page

The legacy ``type`` table maps the gateway's orchestrate items ``{"page": P, "type": T}``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from schemas.errors import BehaviourError

KINDS = ("action", "walk", "sound", "led", "pause", "head")
MAX_DURATION = 600.0
_PARAMS: dict[str, set[str]] = {
    "action": {"page", "say", "say_pt", "file"},
    "walk": {"x", "y", "turn", "duration"},
    "sound": {"file", "say", "say_pt"},
    "led": {"head", "eye"},
    "pause": {"duration"},
    "head": {"pan", "tilt"},
}


@dataclass(frozen=True)
class Behaviour:
    """One entry of the behaviour catalogue: its id, names and what it runs."""

    id: int
    name: str
    name_pt: str
    kind: str
    params: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "name": self.name,
            "name_pt": self.name_pt,
            "kind": self.kind,
            **self.params,
        }


@dataclass
class Item:
    """A resolved choreography item: a kind and checked parameters (SI)."""

    kind: str
    params: dict[str, Any]
    label: str
    behaviour: int | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "label": self.label, "behaviour": self.behaviour, **self.params}


def _key(name: str) -> str:
    return " ".join(name.lower().replace("_", " ").replace("-", " ").split())


def _from_toml(d: dict[str, Any]) -> Behaviour:
    kind = d.get("kind")
    if kind not in KINDS:
        raise BehaviourError(f"behaviour {d.get('id')!r}: kind {kind!r} is not one of {KINDS}")
    params = {k: v for k, v in d.items() if k not in ("id", "name", "name_pt", "kind")}
    # The library file writes head angles in degrees for readability; items are SI.
    for axis in ("pan", "tilt"):
        if f"{axis}_deg" in params:
            params[axis] = math.radians(float(params.pop(f"{axis}_deg")))
    return Behaviour(int(d["id"]), str(d["name"]), str(d.get("name_pt", d["name"])), kind, params)


class BehaviourLibrary:
    def __init__(self, section: dict[str, Any] | None) -> None:
        section = section or {}
        self.types: dict[int, str] = {int(k): str(v) for k, v in section.get("types", {}).items()}
        self.items: dict[int, Behaviour] = {}
        self._names: dict[str, int] = {}
        for raw in section.get("item", []):
            b = _from_toml(raw)
            if b.id in self.items:
                raise BehaviourError(f"behaviour id {b.id} appears twice in the library")
            self.items[b.id] = b
            self._names.setdefault(_key(b.name), b.id)
            self._names.setdefault(_key(b.name_pt), b.id)

    def get(self, ref: Any) -> Behaviour:
        if isinstance(ref, str) and ref.strip().isdigit():
            ref = int(ref)
        if isinstance(ref, int) and not isinstance(ref, bool):
            if ref in self.items:
                return self.items[ref]
            raise BehaviourError(
                f"no behaviour with id {ref} (see the `behaviours` query)", "behaviour"
            )
        if isinstance(ref, str) and _key(ref) in self._names:
            return self.items[self._names[_key(ref)]]
        raise BehaviourError(
            f"no behaviour named {ref!r} (see the `behaviours` query)", "behaviour"
        )

    def listing(self) -> dict[str, Any]:
        return {
            "behaviours": [b.to_dict() for _, b in sorted(self.items.items())],
            "types": {str(k): v for k, v in sorted(self.types.items())},
        }

    def legacy_item(self, page: int, type_: int) -> dict[str, Any]:
        """A choreography item for the gateway's ``{"page": P, "type": T}``."""
        kind = self.types.get(type_)
        if kind is None:
            known = ", ".join(f"{k} = {v}" for k, v in sorted(self.types.items()))
            raise BehaviourError(f"unknown behaviour type {type_}; types are {known}", "type")
        if kind == "action" and page not in self.items:
            return {"page": page}
        b = self.get(page)
        if kind != "behaviour" and b.kind != kind:
            raise BehaviourError(
                f"behaviour {page} ({b.name}) is a {b.kind}, not a {kind} (type {type_})", "page"
            )
        return {"behaviour": page}

    def resolve(self, raw: Any, pages: Any, lang: str = "en") -> Item:
        """Check one item and fill in its behaviour's parameters. ``pages`` answers
        ``page in pages`` for the action pages that exist."""
        if not isinstance(raw, dict):
            raise BehaviourError(f"an item must be a map, got {raw!r}", "items")
        raw = dict(raw)
        behaviour: Behaviour | None = None
        if "behaviour" in raw:
            behaviour = self.get(raw.pop("behaviour"))
            kind, params, label = behaviour.kind, dict(behaviour.params), behaviour.name
            if lang == "pt":
                label = behaviour.name_pt
        elif "page" in raw and "kind" not in raw:
            kind, params, label = "action", {}, f"page {raw.get('page')}"
        elif "kind" in raw:
            kind = raw.pop("kind")
            if kind not in KINDS:
                raise BehaviourError(f"kind {kind!r} is not one of {', '.join(KINDS)}", "kind")
            params, label = {}, kind
        else:
            raise BehaviourError("an item needs a behaviour, a kind or a page", "items")
        unknown = set(raw) - _PARAMS[kind]
        if unknown:
            raise BehaviourError(
                f"{', '.join(sorted(unknown))} is not a parameter of a {kind} item "
                f"(parameters: {', '.join(sorted(_PARAMS[kind]))})",
                sorted(unknown)[0],
            )
        params.update(raw)
        if lang == "pt" and "say_pt" in params:
            params["say"] = params["say_pt"]
        params.pop("say_pt", None)
        _check(kind, params, pages)
        return Item(kind, params, label, behaviour.id if behaviour else None)


def _number(params: dict[str, Any], name: str, low: float, high: float, default: Any = None):
    value = params.get(name, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise BehaviourError(f"{name} must be a number, got {value!r}", name)
    if not low <= value <= high:
        raise BehaviourError(f"{name}={value!r} is outside {low}..{high}", name)
    params[name] = float(value)


def _rgb(params: dict[str, Any], name: str) -> None:
    value = params.get(name)
    if value is None:
        return
    if (
        not isinstance(value, list | tuple)
        or len(value) != 3
        or not all(isinstance(c, int) and not isinstance(c, bool) and 0 <= c <= 255 for c in value)
    ):
        raise BehaviourError(f"{name} must be [r, g, b] with 0..255, got {value!r}", name)
    params[name] = [int(c) for c in value]


def _check(kind: str, params: dict[str, Any], pages: Any) -> None:
    if kind == "action":
        page = params.get("page")
        if isinstance(page, bool) or not isinstance(page, int) or page not in pages:
            raise BehaviourError(f"no action page {page!r} in the motion library", "page")
    elif kind == "walk":
        for axis in ("x", "y", "turn"):
            _number(params, axis, -2.0, 2.0, 0.0)
        _number(params, "duration", 0.0, MAX_DURATION, None)
    elif kind in ("pause",):
        _number(params, "duration", 0.0, MAX_DURATION, None)
    elif kind == "sound":
        if not params.get("file") and not params.get("say"):
            raise BehaviourError("a sound item needs a file or say", "say")
    elif kind == "led":
        _rgb(params, "head")
        _rgb(params, "eye")
        if params.get("head") is None and params.get("eye") is None:
            raise BehaviourError("a led item needs head or eye [r, g, b]", "eye")
    elif kind == "head":
        _number(params, "pan", -math.pi, math.pi, 0.0)
        _number(params, "tilt", -math.pi, math.pi, 0.0)
