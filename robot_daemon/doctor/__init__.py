"""`darwin doctor`: checks of a robot and its computer (docs/doctor.md)."""
