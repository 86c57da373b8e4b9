"""The contracts every program shares: key expressions, message types, units, errors.

Nothing here does I/O except :mod:`schemas.session`, the one Zenoh session helper.
"""

# 2: joints carry radians only (position_deg dropped: SI units on the wire).
SCHEMA_VERSION = 2
