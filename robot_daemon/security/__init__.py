"""Authentication, TLS certificates and access control.

`darwin users`, `darwin certs` and what `--auth`/`--secure` turn on (docs/security.md).
"""
