"""Zenoh security for a listening session (daemon or router): authentication, TLS, access control.

:func:`access_control` turns the role table (``schemas.roles``) and the identities file into
Zenoh's ``access_control`` block: default deny; one rule set per role; subjects are the user
names (user/password logins) and the same names as TLS certificate common names; a policy per
role. :func:`secure` applies it, with the generated ``user:password`` dictionary and, for
``tls/`` endpoints, the certificates of ``darwin certs``, to a session's config.

Links over ``unixsock-stream`` are the daemon's own children (the emulator's control session,
in a private 0700 directory only this user can enter): they get every right, so the emulator
keeps working behind the daemon's access control while no network client can reach it.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from robot_daemon.security import users as users_mod
from robot_daemon.security.paths import ca_paths, robot_paths
from schemas.errors import ConfigError
from schemas.keys import ROOT, Keys, ros_key_space
from schemas.roles import LADDER, READ_OP_VERBS, READ_VERBS, SIM_CONTROL_ROLE, Role

ALL_MESSAGES = [
    "put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
    "liveliness_token", "liveliness_query", "declare_liveliness_subscriber",
]
INTERNAL_PROTOCOLS = ["unixsock-stream"]

# role → ingress queries it adds over the role below it (key expressions).
_QUERIES: dict[Role, list[str]] = {
    Role.OBSERVER: [f"{ROOT}/*/cmd/{v}" for v in sorted(READ_VERBS)]
    + [f"{ROOT}/*/read/{v}" for v in READ_OP_VERBS] + [f"{ROOT}/*/role/observer"],
    Role.OPERATOR: [f"{ROOT}/*/cmd/*", f"{ROOT}/*/replay/control", f"{ROOT}/*/record/control",
                    f"{ROOT}/*/role/operator"],
    Role.ADMIN: [f"{ROOT}/*/admin/*", f"{ROOT}/*/role/admin"],
}
_QUERIES[SIM_CONTROL_ROLE].append(f"{ROOT}/*/sim/control")


def _rules() -> list[dict[str, Any]]:
    def rule(rid: str, messages: list[str], flows: list[str], keys: list[str]) -> dict[str, Any]:
        return {"id": rid, "messages": messages, "flows": flows, "permission": "allow",
                "key_exprs": keys}

    rules = [
        # Everyone watches: subscribe, liveliness, and receives what it subscribed to.
        rule("watch", ["declare_subscriber", "liveliness_query", "declare_liveliness_subscriber"],
             ["ingress"], [f"{ROOT}/**"]),
        # A client's own liveliness token: the arbiter ends its lease when it goes.
        rule("present", ["liveliness_token"], ["ingress"], [f"{ROOT}/*/clients/*"]),
        rule("deliver", ["put", "delete", "reply", "liveliness_token", "declare_subscriber",
                         "declare_queryable", "declare_liveliness_subscriber"],
             ["egress"], [f"{ROOT}/**"]),
        rule("everything", ALL_MESSAGES, ["ingress", "egress"], [f"{ROOT}/**"]),
        # The ROS 2 key space (``darwin ros2`` on this session, ROS nodes): everyone watches,
        # is delivered to and declares its nodes' tokens; only operators publish and call
        # services, since the adapter turns cmd_vel and service calls into commands.
        rule("ros-watch", ["declare_subscriber", "liveliness_query",
                           "declare_liveliness_subscriber", "liveliness_token"],
             ["ingress"], ros_key_space()),
        rule("ros-deliver", ALL_MESSAGES, ["egress"], ros_key_space()),
        rule("ros-drive", ["put", "delete", "query", "reply", "declare_queryable"],
             ["ingress"], ros_key_space()),
    ]
    rules += [rule(f"query-{r}", ["query"], ["ingress"], keys) for r, keys in _QUERIES.items()]
    # The policy stream's actions are publications (schemas/policy.py says why), by operators;
    # the daemon still applies only the lease holder's, signed with its stream key.
    rules.append(rule("policy-stream", ["put"], ["ingress"], [f"{ROOT}/*/policy/action"]))
    return rules


def rules_of(role: Role) -> list[str]:
    """The rule ids a role gets: each role has everything of the roles below it."""
    if role == Role.ROBOT:
        return ["everything"]
    ladder = LADDER[: LADDER.index(role) + 1]
    ros = ["ros-watch", "ros-deliver", *(["ros-drive"] if Role.OPERATOR in ladder else [])]
    stream = ["policy-stream"] if Role.OPERATOR in ladder else []
    return ["watch", "present", "deliver", *(f"query-{r}" for r in ladder), *stream, *ros]


def access_control(
    users: dict[str, users_mod.User], router_zids: list[str] | None = None
) -> dict[str, Any]:
    subjects: list[dict[str, Any]] = [{"id": "internal", "link_protocols": INTERNAL_PROTOCOLS}]
    policies: list[dict[str, Any]] = [{"id": "internal", "rules": ["everything"],
                                       "subjects": ["internal"]}]
    if router_zids:
        # The router this robot joined (``robot_daemon.engine.fleet_join``): it enforces the
        # roles of everyone behind it, and Zenoh gives the robot no user name for it to match.
        subjects.append({"id": "router", "zids": list(router_zids)})
        policies.append({"id": "router", "rules": ["everything"], "subjects": ["router"]})
    for role in (*LADDER, Role.ROBOT):
        names = sorted(u.name for u in users.values() if u.role == role)
        if not names:  # Zenoh refuses an empty subject list
            continue
        ids = [f"{role}-users", f"{role}-certs"]
        subjects += [{"id": ids[0], "usernames": names},
                     {"id": ids[1], "cert_common_names": names}]
        policies.append({"id": str(role), "rules": rules_of(role), "subjects": ids})
    return {"enabled": True, "default_permission": "deny", "rules": _rules(),
            "subjects": subjects, "policies": policies}


def default_certs_dir() -> Path:
    return users_mod.default_users_file().parent / "certs"


@dataclass
class Security:
    """What ``--auth``/``--secure`` turn on for a listening session."""

    users_file: Path
    tls: bool = False  # listen on tls/ with the robot certificate
    mtls: bool = False  # clients prove who they are with certificates instead of passwords
    certs_dir: Path = field(default_factory=default_certs_dir)
    runtime: Path | None = None  # private dir of the generated dictionary
    router_zids: list[str] = field(default_factory=list)  # the joined router, trusted

    def check(self) -> dict[str, users_mod.User]:
        """Everything needed is there (one clear error naming the command that creates it)."""
        users = users_mod.load(self.users_file)
        if not users:
            raise ConfigError(f"{self.users_file} lists nobody: add someone with `darwin users "
                              f"add NAME --role operator --password-file FILE --users "
                              f"{self.users_file}`")
        if self.tls:
            for p in (ca_paths(self.certs_dir).cert, *vars(robot_paths(self.certs_dir)).values()):
                if not Path(p).is_file():
                    raise ConfigError(f"no {p}: create the certificates with `darwin certs --dir "
                                      f"{self.certs_dir} --host ADDRESS`")
        return users

    def apply(self, conf: zenoh.Config) -> None:
        users = self.check()
        if not self.mtls:
            # A private directory for the plaintext dictionary Zenoh reads (removed by close()).
            self.runtime = Path(tempfile.mkdtemp(prefix="darwin-auth-"))
            dictionary = users_mod.write_dictionary(users, self.runtime / "users.dict")
            conf.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(str(dictionary)))
        if self.tls:
            robot = robot_paths(self.certs_dir)
            conf.insert_json5("transport/link/tls/root_ca_certificate",
                              json.dumps(str(ca_paths(self.certs_dir).cert)))
            conf.insert_json5("transport/link/tls/listen_certificate", json.dumps(str(robot.cert)))
            conf.insert_json5("transport/link/tls/listen_private_key", json.dumps(str(robot.key)))
            if self.mtls:
                conf.insert_json5("transport/link/tls/enable_mtls", "true")
        conf.insert_json5(
            "access_control", json.dumps(access_control(users, self.router_zids))
        )

    def close(self) -> None:
        if self.runtime is not None:
            shutil.rmtree(self.runtime, ignore_errors=True)
            self.runtime = None


def check_listen(listen: list[str], security: Security | None) -> list[str]:
    """With TLS every endpoint must be ``tls/``; returns warnings for open addresses."""
    warnings = []
    for ep in listen:
        proto, _, rest = ep.partition("/")
        if security is not None and security.tls and proto != "tls":
            raise ConfigError(f"--secure listens on tls/ endpoints only, not {ep}: write "
                              f"tls/{rest}")
        host = rest.rpartition(":")[0].strip("[]")
        if security is None and proto != "unixsock-stream" and not _loopback(host):
            warnings.append(
                f"warning: {ep} is an open listen address without --secure or --auth: anyone "
                "who can reach it can take the lease and move the robot, or change its "
                "configuration; use --secure (or --auth FILE), or listen on 127.0.0.1"
            )
    return warnings


def _loopback(host: str) -> bool:
    import ipaddress

    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def serve_roles(session: zenoh.Session, keys: Keys) -> list[Any]:
    """One queryable per role (``Keys.role``): access control lets a caller reach only the
    keys of its own roles, so the keys that answer tell the client its role, as the enforcing
    session sees it. Without access control all answer (everyone may do everything)."""
    # Here, not at the top: `darwin up` checks its endpoints with this module and never serves,
    # and the messages' classes cost it ~17 ms of CPU at start.
    from schemas.messages import ok_reply
    from schemas.query import answer

    def serve(role: Role) -> Any:
        key, reply = keys.role(role), ok_reply("role", {"role": str(role)})
        return session.declare_queryable(key, lambda q: answer(q, key, True, reply), complete=True)

    return [serve(r) for r in LADDER]
