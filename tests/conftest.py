"""Shared fixtures live in tests/fixtures/ (one plugin module per part of the system)."""

pytest_plugins = [
    "tests.fixtures.emulator",
    "tests.fixtures.system",
]
