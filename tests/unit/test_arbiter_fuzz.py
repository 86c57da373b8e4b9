"""Fuzz every verb's fields through the real pipeline (decode → field checks → lease → handler)
on a real motion manager and a recording bus: 10⁵ seeded inputs, no internal error, and no bus
write for any input that is refused."""

from __future__ import annotations

import math
import random
from typing import Any

import msgpack

from robot_daemon.arbiter.registry import Reject
from schemas import SCHEMA_VERSION
from schemas.commands import COMMAND_FIELDS
from schemas.errors import CommandError
from schemas.keys import VERBS
from tests.unit.arbiter_rig import ArbiterRig

CASES = 100_000
SEED = 20261123

_STRINGS = ["", "0", "19", "head_pan", "r_knee", "-w/tmp/x", "red", "en", "start", "é" * 3,
            "x" * 300, "\x00", "play", "stop", "home", "sit down"]


def _value(rnd: random.Random, depth: int = 0) -> Any:
    pick = rnd.randrange(14 if depth < 2 else 10)
    if pick == 0:
        return rnd.randint(-3, 300)
    if pick == 1:
        return rnd.choice([0, 1, 20, 200, 253, 255, 256, -1, 2**31, -(2**63), 2**64 - 1])
    if pick == 2:
        return rnd.uniform(-4, 4)
    if pick == 3:
        return rnd.choice([math.nan, math.inf, -math.inf, 1e308, -0.0, 5e-324])
    if pick == 4:
        return rnd.choice([True, False])
    if pick == 5:
        return None
    if pick in (6, 7):
        return rnd.choice(_STRINGS)
    if pick == 8:
        return bytes(rnd.randrange(256) for _ in range(rnd.randrange(4)))
    if pick == 9:
        return [rnd.randint(0, 255) for _ in range(rnd.randrange(4))]
    if pick == 10:
        return [_value(rnd, depth + 1) for _ in range(rnd.randrange(4))]
    if pick == 11:
        return {rnd.choice(_STRINGS[:10]): _value(rnd, depth + 1) for _ in range(rnd.randrange(3))}
    if pick == 12:
        return {"behaviour": rnd.randint(0, 120), "duration": rnd.uniform(-1, 3)}
    return [{"page": rnd.randint(0, 300)}, {"time": rnd.uniform(-1, 2)}]


def _name(rnd: random.Random, declared: list[str]) -> str:
    if declared and rnd.random() < 0.85:
        name = rnd.choice(declared)
        r = rnd.random()
        if r < 0.06:
            return name.upper()
        if r < 0.12 and len(name) > 1:
            i = rnd.randrange(len(name))
            return name[:i] + name[i + 1 :]
        return name
    return rnd.choice(["id", "ids", "X", "duraton", "speed", "enable", "foo", "op", "data"])


def _fields(rnd: random.Random, verb: str) -> dict[str, Any]:
    declared = list(COMMAND_FIELDS[verb])
    return {_name(rnd, declared): _value(rnd) for _ in range(rnd.randrange(5))}


def test_every_verbs_fields_fuzzed_never_reach_an_internal_error_or_write_when_refused() -> None:
    rnd = random.Random(SEED)
    rig = ArbiterRig(allow_eeprom=bool(rnd.getrandbits(1)))
    token = rig.acquire("fuzzer")
    outcomes = {"applied": 0, "refused": 0}
    for i in range(CASES):
        verb = VERBS[i % len(VERBS)]
        fields = _fields(rnd, verb)
        envelope: dict[str, Any] = {"v": SCHEMA_VERSION, "client": "fuzzer"}
        if rnd.random() < 0.8:
            envelope["lease_token"] = token
        if rnd.random() < 0.02:
            envelope[rnd.choice(["v", "client", "lease_token", "client_name"])] = _value(rnd)
        if verb == "lease" and fields.get("op") in ("release", "acquire"):
            fields["op"] = "status"  # keep the lease for the rest of the run
        payload = msgpack.packb({**envelope, **fields}, use_bin_type=True)
        writes_before = len(rig.bus.writes)
        try:
            applied = rig.send_payload(verb, payload)
        except Reject as exc:
            outcomes["refused"] += 1
            assert exc.code != "internal", (verb, fields, exc)
            assert len(rig.bus.writes) == writes_before, (verb, fields, exc)
            assert len(exc.message) < 1000, (verb, exc.message[:100])  # never the whole value
        except CommandError as exc:  # handlers' own refusals (behaviours, fields)
            outcomes["refused"] += 1
            assert exc.code != "internal", (verb, fields, exc)
            assert len(rig.bus.writes) == writes_before, (verb, fields, exc)
        else:
            outcomes["applied"] += 1
            assert isinstance(applied, dict)
        if i % 500 == 0:
            rig.manager.halt()  # the fuzz never walks the robot for long
    assert outcomes["applied"] > 1000 and outcomes["refused"] > 10_000, outcomes
