"""The contracts every program shares: key expressions, message types, units, errors.

Nothing here does I/O except :mod:`schemas.session`, the one Zenoh session helper.
"""

SCHEMA_VERSION = 1
