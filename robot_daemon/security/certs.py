"""TLS material for ``darwin certs``: a CA, a robot (server) certificate and client certificates.

Written with the ``cryptography`` library as PEM files Zenoh reads directly
(``transport/link/tls/*``). A client certificate's common name is the user name: access control
matches it (``cert_common_names``) exactly as it matches a user/password login. Private keys are
written 0600; the CA key never leaves the certificates directory.
"""

from __future__ import annotations

import datetime
import ipaddress
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from robot_daemon.security.paths import (
    CertPaths,
    ca_paths,
    client_paths,
    robot_paths,
    write_private,
)
from schemas.errors import ConfigError

CA_NAME = "darwin-ca"
ROBOT_NAME = "robot"
DAYS = 825  # the longest validity clients commonly accept for a leaf certificate


def _key_pem(key: ec.EllipticCurvePrivateKey) -> bytes:
    return key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )


def _load(paths: CertPaths) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
    try:
        cert = x509.load_pem_x509_certificate(paths.cert.read_bytes())
        key = serialization.load_pem_private_key(paths.key.read_bytes(), None)
    except (OSError, ValueError) as exc:
        raise ConfigError(
            f"cannot read the CA in {paths.cert.parent} ({exc}); create it with `darwin certs "
            f"--dir {paths.cert.parent}`"
        ) from None
    if not isinstance(key, ec.EllipticCurvePrivateKey):
        raise ConfigError(f"{paths.key} is not an EC key made by `darwin certs`")
    return cert, key


def _name(common_name: str) -> x509.Name:
    return x509.Name(
        [
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "darwin-zenoh"),
            x509.NameAttribute(NameOID.COMMON_NAME, common_name),
        ]
    )


def _builder(
    subject: str, issuer: x509.Name, key: ec.EllipticCurvePrivateKey
) -> x509.CertificateBuilder:
    now = datetime.datetime.now(datetime.UTC)
    return (
        x509.CertificateBuilder()
        .subject_name(_name(subject))
        .issuer_name(issuer)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=DAYS))
    )


def create_ca(directory: Path, force: bool = False) -> CertPaths:
    """The CA every robot and client of this installation trusts (kept if it exists)."""
    paths = ca_paths(directory)
    if paths.cert.exists() and not force:
        return paths
    key = ec.generate_private_key(ec.SECP256R1())
    cert = (
        _builder(CA_NAME, _name(CA_NAME), key)
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=False,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    write_private(paths.key, _key_pem(key))
    paths.cert.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return paths


def _san(host: str) -> x509.GeneralName:
    try:
        return x509.IPAddress(ipaddress.ip_address(host))
    except ValueError:
        return x509.DNSName(host)


def issue(
    directory: Path, paths: CertPaths, common_name: str, hosts: list[str], server: bool
) -> CertPaths:
    """A leaf certificate signed by the CA in ``directory``: a server one (``hosts`` as subject
    alternative names, which TLS clients check against the address they dial) or a client one."""
    ca_cert, ca_key = _load(ca_paths(directory))
    key = ec.generate_private_key(ec.SECP256R1())
    usage = ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH
    builder = (
        _builder(common_name, ca_cert.subject, key)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(x509.ExtendedKeyUsage([usage]), critical=False)
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), critical=False
        )
    )
    if hosts:
        builder = builder.add_extension(
            x509.SubjectAlternativeName([_san(h) for h in hosts]), critical=False
        )
    cert = builder.sign(ca_key, hashes.SHA256())
    write_private(paths.key, _key_pem(key))
    paths.cert.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return paths


def create_robot(directory: Path, hosts: list[str]) -> CertPaths:
    return issue(directory, robot_paths(directory), ROBOT_NAME, hosts, server=True)


def create_client(directory: Path, user: str) -> CertPaths:
    # A client of the robot may also be a robot's daemon joining a router, hence also SANs-free.
    return issue(directory, client_paths(directory, user), user, [], server=False)


def common_name(cert_file: Path) -> str:
    cert = x509.load_pem_x509_certificate(cert_file.read_bytes())
    return str(cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value)
