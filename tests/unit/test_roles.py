"""The role table, the access-control config made from it, and how clients find credentials."""

from __future__ import annotations

from pathlib import Path

import pytest

from robot_daemon.security.acl import access_control, check_listen, rules_of
from robot_daemon.security.users import User
from schemas.errors import ConfigError, ForbiddenError, command_error
from schemas.keys import VERBS, Keys
from schemas.roles import Role, allows, check, command_key, required_role, verbs_allowed
from schemas.session import credentials, server_config


def test_each_role_includes_the_one_below() -> None:
    assert verbs_allowed(Role.OBSERVER) == {"config", "behaviours", "walk_params", "offsets"}
    assert verbs_allowed(Role.OPERATOR) == set(VERBS) == verbs_allowed(Role.ADMIN)
    write = {"id": 19, "address": 25, "data": [1]}
    assert required_role("registers", write) == Role.ADMIN
    assert required_role("registers", {"id": 19, "address": 25, "length": 1}) == Role.OPERATOR
    assert required_role("pages", {"op": "put"}) == Role.ADMIN
    assert required_role("pages", {"op": "list"}) == Role.OPERATOR
    assert allows(Role.ADMIN, "registers", write) and not allows(Role.OPERATOR, "registers", write)
    assert allows(None, "registers", write)  # unknown role: the robot decides


def test_a_refusal_names_the_role_that_would_allow_it() -> None:
    with pytest.raises(ForbiddenError) as info:
        check(Role.OBSERVER, "halt", {}, "bob")
    assert info.value.role == "operator"
    assert "halt needs the operator role (bob is observer)" in str(info.value)
    assert type(command_error("forbidden", "x")) is ForbiddenError


def test_admin_only_operations_have_a_key_of_their_own() -> None:
    keys = Keys("op1")
    assert command_key(keys, "registers", {"data": [1]}) == "darwin/op1/admin/registers"
    assert command_key(keys, "registers", {"length": 1}) == "darwin/op1/cmd/registers"
    assert command_key(keys, "walk", {"op": "start"}) == "darwin/op1/cmd/walk"


def test_reads_that_share_a_verb_with_a_write_have_a_key_observers_may_query() -> None:
    keys = Keys("op1")
    assert command_key(keys, "walk_params", {}) == "darwin/op1/read/walk_params"
    assert command_key(keys, "walk_params", {"set": {"x": 1}}) == "darwin/op1/cmd/walk_params"
    assert allows(Role.OBSERVER, "walk_params", {})
    assert not allows(Role.OBSERVER, "walk_params", {"set": {"x": 1}})
    rules = {r["id"]: r for r in access_control({"b": User("b", Role.OBSERVER, "pw-1")})["rules"]}
    assert "darwin/*/read/walk_params" in rules["query-observer"]["key_exprs"]
    assert "darwin/*/sim/control" in rules["query-admin"]["key_exprs"]


def test_the_ros_key_space_is_watched_by_observers_and_driven_by_operators() -> None:
    assert "ros-watch" in rules_of(Role.OBSERVER) and "ros-drive" not in rules_of(Role.OBSERVER)
    assert "ros-drive" in rules_of(Role.OPERATOR) and "ros-drive" in rules_of(Role.ADMIN)
    rules = {r["id"]: r for r in access_control({"b": User("b", Role.OBSERVER, "pw-1")})["rules"]}
    assert {"@ros2_lv/**", "0/**", "232/**"} <= set(rules["ros-drive"]["key_exprs"])
    assert not any(k.startswith("darwin") for k in rules["ros-drive"]["key_exprs"])


def test_access_control_gives_each_role_its_rules_by_name_and_certificate() -> None:
    acl = access_control({
        "bob": User("bob", Role.OBSERVER, "password-1"),
        "carol": User("carol", Role.ADMIN, None),
    })
    assert acl["enabled"] is True and acl["default_permission"] == "deny"
    subjects = {s["id"]: s for s in acl["subjects"]}
    assert subjects["observer-users"]["usernames"] == ["bob"]
    assert subjects["admin-certs"]["cert_common_names"] == ["carol"]
    assert "operator-users" not in subjects  # nobody: Zenoh refuses an empty list
    policies = {p["id"]: p for p in acl["policies"]}
    assert policies["observer"]["rules"] == rules_of(Role.OBSERVER)
    assert set(rules_of(Role.OBSERVER)) < set(rules_of(Role.OPERATOR)) < set(rules_of(Role.ADMIN))
    rules = {r["id"]: r for r in acl["rules"]}
    assert "darwin/*/admin/*" in rules["query-admin"]["key_exprs"]
    assert "darwin/*/cmd/*" not in rules["query-observer"]["key_exprs"]


def test_the_generated_access_control_is_accepted_by_zenoh() -> None:
    import json

    import zenoh

    conf = server_config([])
    acl = access_control({"bob": User("bob", Role.OPERATOR, "password-1")})
    conf.insert_json5("access_control", json.dumps(acl))
    # Zenoh checks the rules, subjects and policies when the session opens.
    zenoh.open(conf).close()
    acl["policies"][0]["rules"] = ["no-such-rule"]
    conf = server_config([])
    conf.insert_json5("access_control", json.dumps(acl))
    with pytest.raises(zenoh.ZError):
        zenoh.open(conf)


def test_open_listen_addresses_are_warned_about_and_tls_is_required_when_secure() -> None:
    assert check_listen(["tcp/127.0.0.1:7447", "tcp/[::1]:7447"], None) == []
    (warning,) = check_listen(["tcp/0.0.0.0:7447"], None)
    assert "anyone who can reach it can take the lease" in warning
    from robot_daemon.security.acl import Security

    with pytest.raises(ConfigError, match=r"tls/0\.0\.0\.0:7447"):
        check_listen(["tcp/0.0.0.0:7447"], Security(Path("u"), tls=True))


def test_credentials_come_from_arguments_then_environment_then_the_client_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    client_file = tmp_path / "client.toml"
    pw = tmp_path / "pw"
    pw.write_text("file-password\n")
    client_file.write_text(f'user = "filer"\npassword_file = "{pw}"\nca = "/x/ca.pem"\n')
    monkeypatch.setenv("DARWIN_CLIENT_CONFIG", str(client_file))
    for name in ("DARWIN_USER", "DARWIN_PASSWORD", "DARWIN_PASSWORD_FILE", "DARWIN_CERT"):
        monkeypatch.delenv(name, raising=False)
    c = credentials()
    assert (c.user, c.password, c.ca) == ("filer", "file-password", "/x/ca.pem")
    monkeypatch.setenv("DARWIN_USER", "envy")
    monkeypatch.setenv("DARWIN_PASSWORD", "env-password")
    monkeypatch.setenv("DARWIN_PASSWORD_FILE", "")
    client_file.write_text('user = "filer"\n')
    c = credentials()
    assert (c.user, c.password) == ("envy", "env-password")
    c = credentials(user="arg", password="arg-password")
    assert (c.user, c.password) == ("arg", "arg-password")
    monkeypatch.delenv("DARWIN_PASSWORD")
    with pytest.raises(ValueError, match="has no password"):
        credentials()
    with pytest.raises(ValueError, match="both --cert and --key"):
        credentials(user="x", password="y", cert="c.pem")
