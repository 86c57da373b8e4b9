"""Shared fixtures live in tests/fixtures/ (one plugin module per part of the system)."""

import os
import tempfile

pytest_plugins = [
    "tests.fixtures.emulator",
    "tests.fixtures.system",
]

# Daemons started by the tests (in-process or `darwin up`) read the user's own action pages
# from here, never from the developer's ~/.config/darwin/motions; a test that saves pages
# points DARWIN_MOTIONS (or [motion] user_library) at a folder of its own.
os.environ.setdefault("DARWIN_MOTIONS", tempfile.mkdtemp(prefix="darwin-test-motions-"))
