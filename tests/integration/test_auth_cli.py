"""`darwin users`, `darwin certs` and the one-line errors of `darwin up --auth/--secure`, run as
the programs they are."""

from __future__ import annotations

import stat
from pathlib import Path

from cryptography import x509
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from tests.fixtures.system import run_darwin


def mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_users_add_list_remove(tmp_path: Path) -> None:
    users = tmp_path / "users.toml"
    pw = tmp_path / "pw"
    pw.write_text("a-long-password\n")
    for name, role in (("alice", "operator"), ("bob", "observer")):
        done = run_darwin("users", "add", name, "--role", role, "--password-file", str(pw),
                          "--users", str(users))
        assert done.returncode == 0, done.stderr
    assert run_darwin("users", "add", "carol", "--role", "admin", "--cert-only",
                      "--users", str(users)).returncode == 0
    assert mode(users) == 0o600
    listed = run_darwin("users", "list", "--users", str(users))
    assert listed.stdout.splitlines() == [
        "bob: observer (password)", "alice: operator (password)", "carol: admin (certificate)",
    ]
    assert "a-long-password" not in listed.stdout
    # A role changes by adding the user again.
    run_darwin("users", "add", "bob", "--role", "admin", "--password-file", str(pw),
               "--users", str(users))
    assert run_darwin("users", "remove", "alice", "--users", str(users)).returncode == 0
    listed = run_darwin("users", "list", "--users", str(users))
    assert listed.stdout.splitlines() == ["bob: admin (password)", "carol: admin (certificate)"]


def test_users_refuses_bad_input_with_one_line(tmp_path: Path) -> None:
    users = tmp_path / "users.toml"
    pw = tmp_path / "pw"
    pw.write_text("a-long-password\n")
    short = tmp_path / "short"
    short.write_text("abc\n")
    cases = [
        (("add", "bob", "--role", "boss", "--password-file", str(pw)), "role 'boss'"),
        (("add", "bo:b", "--role", "observer", "--password-file", str(pw)), "user name 'bo:b'"),
        (("add", "bob", "--role", "observer", "--password-file", str(short)), "shorter than 8"),
        (("add", "bob", "--role", "observer", "--password-file", str(tmp_path / "nope")),
         "cannot read the password file"),
        (("remove", "nobody"), "no identities file"),
    ]
    for args, expected in cases:
        done = run_darwin("users", *args, "--users", str(users))
        assert done.returncode != 0
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and expected in lines[0], done.stderr
    assert not users.exists()


def test_certs_makes_a_ca_a_robot_certificate_and_client_certificates(tmp_path: Path) -> None:
    out = tmp_path / "certs"
    done = run_darwin("certs", "--dir", str(out), "--host", "10.0.0.5", "--host", "op1.local",
                      "--client", "alice")
    assert done.returncode == 0, done.stderr
    assert {line.split(":", 1)[0] for line in done.stdout.splitlines()} == {
        "ca", "robot", "client alice", "client alice key"}
    for key in ("ca.key", "robot.key", "alice.key"):
        assert mode(out / key) == 0o600
    ca = x509.load_pem_x509_certificate((out / "ca.pem").read_bytes())
    robot = x509.load_pem_x509_certificate((out / "robot.pem").read_bytes())
    alice = x509.load_pem_x509_certificate((out / "alice.pem").read_bytes())
    robot.verify_directly_issued_by(ca)
    alice.verify_directly_issued_by(ca)
    san = robot.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert [str(ip) for ip in san.get_values_for_type(x509.IPAddress)] == ["10.0.0.5"]
    assert san.get_values_for_type(x509.DNSName) == ["op1.local"]
    cn = alice.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value
    assert cn == "alice"
    usage = alice.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value
    assert ExtendedKeyUsageOID.CLIENT_AUTH in usage
    # A second run keeps the CA (certificates already handed out stay valid).
    again = run_darwin("certs", "--dir", str(out), "--client", "bob")
    assert again.returncode == 0
    assert x509.load_pem_x509_certificate((out / "ca.pem").read_bytes()) == ca
    assert "kept" in again.stdout


def test_up_secure_without_files_names_the_command_that_makes_them(tmp_path: Path) -> None:
    users = tmp_path / "users.toml"
    done = run_darwin("up", "--secure", "--auth", str(users), "--certs", str(tmp_path / "c"),
                      "--no-gateway", timeout=60)
    assert done.returncode == 1
    assert "darwin users add" in done.stderr.strip().splitlines()[-1], done.stderr
    pw = tmp_path / "pw"
    pw.write_text("a-long-password\n")
    run_darwin("users", "add", "op", "--role", "operator", "--password-file", str(pw),
               "--users", str(users))
    done = run_darwin("up", "--secure", "--auth", str(users), "--certs", str(tmp_path / "c"),
                      "--no-gateway", timeout=60)
    assert done.returncode == 1
    assert "darwin certs" in done.stderr.strip().splitlines()[-1], done.stderr
    users.chmod(0o644)
    done = run_darwin("up", "--auth", str(users), "--no-gateway", timeout=60)
    assert done.returncode == 1 and "chmod 600" in done.stderr, done.stderr
    users.chmod(0o600)
    done = run_darwin("up", "--secure", "--auth", str(users), "--listen",
                      "tcp/127.0.0.1:0", "--no-gateway", timeout=60)
    assert done.returncode == 1 and "tls/" in done.stderr, done.stderr
