"""The optional C extension of the tick's hot path (robot_daemon/_hotpath.c). Everything else
is in pyproject.toml. ``optional=True``: without a C compiler or Python's headers pip still
installs the project (setuptools prints a warning) and the daemon runs the same path in Python
(robot_daemon/hotpath.py says which in one line at start)."""

import platform
import struct

from setuptools import Extension, setup

# The extension must give the bits of the Python it stands in for: no fused multiply-add, and on
# 32-bit x86, whose Python computes on the x87 unit, every assignment rounded to a double as
# each Python float operation is. gcc's default for GNU C keeps x87's excess precision;
# -fexcess-precision=standard alone still differed in the last bit from Debian 12's i386 Python
# in 12 % of leg IKs at -O2 (and SSE2 arithmetic in 0.3 %: Python's x87 rounds twice), with
# -ffloat-store too in none of 200 000 (tests/unit/test_hotpath.py, run in the i386 root).
flags = ["-ffp-contract=off"]
if struct.calcsize("P") == 4 and platform.machine().lower() in {"i386", "i486", "i586", "i686",
                                                                  "x86"}:
    flags += ["-fexcess-precision=standard", "-ffloat-store"]

setup(ext_modules=[Extension("robot_daemon._hotpath", ["robot_daemon/_hotpath.c"],
                             extra_compile_args=flags, optional=True)])
