"""Shared fixtures live in tests/fixtures/ (one plugin module per part of the system)."""

import atexit
import os
import shutil
import tempfile

pytest_plugins = [
    "tests.fixtures.emulator",
    "tests.fixtures.system",
    "tests.fixtures.zenoh_pair",
]

# Daemons started by the tests (in-process or `darwin up`) read the user's own action pages
# from here, never from the developer's ~/.config/darwin/motions; a test that saves pages
# points DARWIN_MOTIONS (or [motion] user_library) at a folder of its own.
_MOTIONS = tempfile.mkdtemp(prefix="darwin-test-motions-")
os.environ["DARWIN_MOTIONS"] = _MOTIONS
atexit.register(shutil.rmtree, _MOTIONS, ignore_errors=True)
