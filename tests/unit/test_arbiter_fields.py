"""Every verb's fields are declared once; anything else is refused, naming the field, before
the lease check and the handler: nothing reaches the bus."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import pytest

from gateway.translate import Command
from robot_daemon.arbiter.core import BUS_VERBS
from robot_daemon.arbiter.protected import PROTECTED
from robot_daemon.arbiter.registry import REGISTRY, SPECS, Reject, Request
from robot_daemon.bus.tables import CM730, MX28
from robot_daemon.motion.manager import MotionManager
from schemas.commands import COMMAND_FIELDS, SPEC, Field, Op, Verb, needs_lease, operation
from schemas.errors import ErrorCode
from schemas.keys import LEASE_FREE_VERBS, VERBS, Keys
from schemas.roles import ADMIN_OPS, READ_VERBS, Role, command_key, required_role
from tests.unit.arbiter_rig import ArbiterRig

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def rig() -> ArbiterRig:
    return ArbiterRig()


def test_every_verb_is_declared_and_registered_with_its_declaration() -> None:
    ArbiterRig()
    assert set(SPEC) == set(COMMAND_FIELDS) == set(VERBS) == set(REGISTRY)
    assert all(SPECS[v] is COMMAND_FIELDS[v] is SPEC[v].fields for v in VERBS)


def _client_verbs() -> set[str]:
    """The verbs the Python clients send: the first argument of every ``command("verb", …)``
    call in clients/ (the Robot API, the modules it is built from and its users)."""
    sent: set[str] = set()
    for path in (REPO / "clients").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr == "command" and node.args
                    and isinstance(node.args[0], ast.Constant)):
                sent.add(node.args[0].value)
    return sent


def test_every_verb_has_a_client_method_and_clients_send_only_verbs() -> None:
    sent = _client_verbs()
    assert set(VERBS) <= sent, f"verbs no Robot method sends: {set(VERBS) - sent}"
    assert sent <= set(VERBS), f"clients send verbs the spec does not declare: {sent - set(VERBS)}"


def test_the_spec_decides_the_lease_the_roles_and_the_bus_budget() -> None:
    """Every table is derived from the spec, so they cannot disagree: the arbiter's and the
    gateway's lease rule are the same function (they used to differ on register reads)."""
    assert {v for v, s in SPEC.items() if not s.lease} == LEASE_FREE_VERBS
    assert {v for v, s in SPEC.items() if s.bus} == BUS_VERBS
    assert set(ADMIN_OPS) == {v for v, s in SPEC.items() if s.admin_ops}
    assert {v for v, s in SPEC.items() if s.read} == READ_VERBS
    read = {"id": 1, "address": 36, "length": 2}
    write = {"id": 1, "address": 36, "data": [0]}
    cases = [("registers", read, False), ("registers", write, True), ("walk_params", {}, False),
             ("walk_params", {"set": {"x_offset": 0.0}}, True), ("walk", {"op": "stop"}, False),
             ("walk", {"op": "start"}, True), ("halt", {}, False), ("pose", {}, True),
             ("no_such_verb", {}, True)]
    for verb, fields, expected in cases:
        assert needs_lease(verb, fields) is expected, (verb, fields)
        assert Command(verb, fields).needs_lease is expected, (verb, fields)
    for verb, spec in SPEC.items():
        assert all(not needs_lease(verb, {"op": op}) for op in spec.free_ops if op != "read")


# A value of each field kind that passes the kind check (the handler may still refuse it).
_SAMPLE = {"int": 1, "number": 0.0, "bool": True, "ref": 1, "rgb": [0, 0, 0], "list": [],
           "map": {}}


def _sample(f: Field) -> object:
    return f.choices[0] if f.choices else _SAMPLE.get(f.kind, "x")


def _chooser(spec: Verb, op: Op) -> dict[str, object]:
    """The fields that choose ``op``: its name, or the field whose presence implies it."""
    if op.when is not None:
        return {op.when: _sample(spec.fields[op.when])}
    return {"op": op.name} if "op" in spec.fields else {}


_VERB_OPS = [(v.name, o) for v in SPEC.values() for o in v.ops]


@pytest.mark.parametrize(("verb", "op"), _VERB_OPS, ids=[f"{v}-{o.label}" for v, o in _VERB_OPS])
def test_every_operation_behaves_as_its_spec_says(verb: str, op: Op) -> None:
    """Spec and behaviour agree for each verb × op: the arbiter works the op out as declared
    (and hands it to the handler), refuses it without the lease exactly when it needs the lease,
    routes and roles it as declared, and takes exactly its declared fields. (The spec once said
    `policy` without an op needed the lease while its handler did a status read.)"""
    spec = SPEC[verb]
    chooser = _chooser(spec, op)
    assert operation(verb, chooser) == op
    # the lease: the arbiter's check and every adapter's rule (needs_lease) agree with the op
    assert needs_lease(verb, chooser) is op.lease
    assert Command(verb, chooser).needs_lease is op.lease
    rig = ArbiterRig()
    try:
        reply = rig.send(verb, client="nolease", **chooser)
    except Reject as exc:
        # (The lease verb's own renew and release are refused to a client that holds none.)
        refused = exc.code == ErrorCode.NO_LEASE and verb != "lease"
        assert refused is op.lease, exc.message
    else:
        assert not op.lease, f"{verb} {op.label} ran without the lease"
        assert reply.get("op", op.name) == op.name
    # the role and the key it travels on
    want = {"observer": Role.OBSERVER, "operator": Role.OPERATOR, "admin": Role.ADMIN}[op.access]
    assert required_role(verb, chooser) == want
    keys = Keys("op1")
    where = {Role.ADMIN: keys.admin(verb), Role.OPERATOR: keys.cmd(verb)}.get(
        want, keys.cmd(verb) if spec.read else keys.read(verb)
    )
    assert command_key(keys, verb, chooser) == where
    # the fields: each of its own is taken, each other field of the verb is refused naming it
    for name in op.fields:
        assert operation(verb, {**chooser, name: _sample(spec.fields[name])}) == op
    choosers = {"op"} | {o.when for o in spec.ops if o.when}
    for name in set(spec.fields) - set(op.fields) - choosers:
        with pytest.raises(Reject) as info:
            operation(verb, {**chooser, name: _sample(spec.fields[name])})
        assert info.value.field == name and "takes no field" in info.value.message


def test_a_policy_status_read_needs_no_lease(rig: ArbiterRig) -> None:
    """`policy` without an op is its status read, to the spec as to the handler."""
    assert operation("policy", {}).name == "status" and not needs_lease("policy", {})
    try:
        reply = rig.send("policy", client="nolease")
    except Reject as exc:  # a daemon without the policy loop says so; never "needs the lease"
        assert exc.code == ErrorCode.UNAVAILABLE, exc.message
    else:
        assert reply["op"] == "status"


def test_handlers_never_parse_op() -> None:
    """The arbiter works the operation out once (req.op); no handler reads the op field."""
    verbs = REPO / "robot_daemon" / "arbiter" / "verbs"
    for path in verbs.glob("*.py"):
        tree = ast.parse(path.read_text())
        reply_keys = {id(k) for d in ast.walk(tree) if isinstance(d, ast.Dict) for k in d.keys}
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and node.value == "op":
                # "op" only as a key of a reply ({"op": ...}), never read from the fields
                assert id(node) in reply_keys, f"{path.name}:{node.lineno} reads the op field"


@pytest.mark.parametrize(
    ("verb", "fields", "field", "hint"),
    [
        ("torque", {"enable": False, "id": 5}, "id", "ids"),  # turned off all 20 joints
        ("walk", {"X": 0.1}, "X", "x"),  # walked in place
        ("pose", {"positions": {"head_pan": 0.1}, "duraton": 3.0}, "duraton", "duration"),
        ("led", {"head": [1, 2, 3], "colour": 1}, "colour", None),
        ("halt", {"now": True}, "now", None),
    ],
)
def test_a_misspelt_or_unknown_field_is_refused_naming_it(
    rig: ArbiterRig, verb: str, fields: dict, field: str, hint: str | None
) -> None:
    token = rig.acquire()
    with pytest.raises(Reject) as info:
        rig.send(verb, lease_token=token, **fields)
    assert info.value.code == "invalid" and info.value.field == field
    if hint:
        assert f"did you mean {hint!r}" in info.value.message
    assert rig.bus.writes == []
    assert not rig.manager.module("walking").running


@pytest.mark.parametrize("verb", [v for v in VERBS if "op" in COMMAND_FIELDS[v]])
@pytest.mark.parametrize("op", [["start"], {"a": 1}, 3, True, "x" * 10_000])
def test_an_op_of_the_wrong_type_is_an_error_not_a_crash(
    rig: ArbiterRig, verb: str, op: object
) -> None:
    with pytest.raises(Reject) as info:
        rig.send(verb, op=op)
    assert info.value.field == "op" and info.value.code in ("invalid", "out_of_range")
    assert len(info.value.message) < 200


def test_wrong_types_name_the_field(rig: ArbiterRig) -> None:
    token = rig.acquire()
    for verb, fields, field in [
        ("joint", {"id": 1, "position": "0.1"}, "position"),
        ("joint", {"id": 1.5, "position": 0.1}, "id"),
        ("joint", {"id": 1, "position": float("nan")}, "position"),
        ("torque", {"enable": 0}, "enable"),
        ("torque", {"enable": True, "ids": "1,2"}, "ids"),
        ("led", {"head": [1, 2]}, "head"),
        ("pose", {"positions": [0.1]}, "positions"),
        ("walk_params", {"set": 3}, "set"),
    ]:
        with pytest.raises(Reject) as info:
            rig.send(verb, lease_token=token, **fields)
        assert (info.value.code, info.value.field) == ("invalid", field), (verb, fields)
    assert rig.bus.writes == []


def test_strings_and_lists_are_capped_and_errors_echo_a_short_prefix(rig: ArbiterRig) -> None:
    token = rig.acquire()
    with pytest.raises(Reject) as info:
        rig.send("lease", op="acquire", name="n" * 1_000_000)
    assert info.value.code == "out_of_range" and len(info.value.message) < 200
    with pytest.raises(Reject) as info:
        rig.send("torque", lease_token=token, enable=False, ids=list(range(1000)))
    assert info.value.code == "out_of_range" and info.value.field == "ids"
    with pytest.raises(Reject) as info:
        rig.send("joint", lease_token=token, name="x" * 200_000, position=0.0)
    assert len(info.value.message) < 200
    with pytest.raises(Reject) as info:
        rig.send("head", lease_token=token, pan="p" * 900)
    assert info.value.field == "pan" and len(info.value.message) < 200
    assert rig.bus.writes == []


def test_joint_speed_zero_is_the_servo_maximum(rig: ArbiterRig) -> None:
    token = rig.acquire()
    applied = rig.send("joint", lease_token=token, name="head_pan", position=0.2, speed=0)
    assert applied["speed"] == rig.robot.max_speed
    direct = rig.manager.module("direct")
    assert direct._pending[-1][2] == rig.robot.max_speed


def test_a_reused_client_id_cannot_command_or_release(rig: ArbiterRig) -> None:
    token = rig.acquire("holder")
    for verb, fields in [
        ("joint", {"id": 1, "position": 0.1}),
        ("walk", {"op": "start", "x": 0.01}),
        ("torque", {"enable": False}),
    ]:
        with pytest.raises(Reject) as info:
            rig.send(verb, client="holder", **fields)  # the public id, no secret
        assert info.value.code == "busy"
    applied = rig.send("lease", client="holder", op="release")
    assert applied["released"] is False and rig.lease.holder is not None
    assert rig.bus.writes == [] and not rig.manager.module("walking").running
    assert rig.send("joint", client="holder", lease_token=token, id=19, position=0.1)


# -- registers that can disable or lose hardware ------------------------------------------------
def test_the_protected_set_is_data_keyed_by_the_register_tables() -> None:
    assert {CM730.DXL_POWER, MX28.ID, CM730.ID, MX28.BAUD_RATE} <= PROTECTED
    assert MX28.GOAL_POSITION not in PROTECTED and CM730.LED_HEAD not in PROTECTED


@pytest.mark.parametrize(
    ("dxl_id", "address", "data"),
    [
        (200, CM730.DXL_POWER.reg.address, [0]),  # cut power to every servo
        (19, MX28.ID.reg.address, [42]),  # lose a servo
        (19, MX28.BAUD_RATE.reg.address, [3]),
        (19, MX28.STATUS_RETURN_LEVEL.reg.address, [0]),
        (19, MX28.CW_ANGLE_LIMIT.reg.address, [0, 0]),
        (19, MX28.TORQUE_LIMIT.reg.address, [0, 0]),
    ],
)
def test_hardware_writes_are_refused_without_the_admin_switch(
    dxl_id: int, address: int, data: list[int]
) -> None:
    rig = ArbiterRig(allow_eeprom=True)  # ordinary EEPROM is not enough
    token = rig.acquire()
    with pytest.raises(Reject) as info:
        rig.send("registers", lease_token=token, id=dxl_id, address=address, data=data)
    assert info.value.code == "refused" and "--allow-hardware-writes" in info.value.message
    assert rig.bus.writes == []


def test_an_id_write_reports_the_true_outcome_at_the_new_id() -> None:
    rig = ArbiterRig(allow_eeprom=True, allow_hardware_writes=True)
    token = rig.acquire()
    with pytest.raises(Reject) as info:  # two devices with one ID answer over each other
        rig.send("registers", lease_token=token, id=19, address=3, data=[20])
    assert info.value.code == "refused" and rig.bus.writes == []
    applied = rig.send("registers", lease_token=token, id=19, address=3, data=[42])
    assert applied["verified"] is True and applied["id"] == 42 and applied["moved_from"] == 19
    assert rig.bus.reads[-1] == (42, 3, 1)  # read back where the servo answers now


def test_dxl_power_with_the_switch_is_written_and_read_back() -> None:
    rig = ArbiterRig(allow_hardware_writes=True)
    token = rig.acquire()
    applied = rig.send("registers", lease_token=token, id=200, address=24, data=[1])
    assert applied["readback"] == [1] and applied["verified"] is True


@pytest.mark.parametrize(
    ("verb", "fields", "message"),
    [
        ("walk", {"op": "stop"}, "the walking module is not part of this daemon"),
        ("playball", {"op": "stop"}, "ball play is not part of this daemon"),
        ("joint", {"id": 19, "position": 0.1}, "direct joint control is not part of this daemon"),
    ],
)
def test_a_verb_whose_module_this_daemon_lacks_is_unavailable_naming_it(
    rig: ArbiterRig, verb: str, fields: dict, message: str
) -> None:
    ctx = dataclasses.replace(rig.context(), manager=MotionManager(rig.robot))
    with pytest.raises(Reject) as info:
        REGISTRY[verb](Request(verb, "c1", "tester", fields), ctx)
    assert info.value.code == "unavailable" and info.value.message == message
