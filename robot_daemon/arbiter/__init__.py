"""The arbiter: one queryable per verb, the control lease, and one queue to the motion thread.

Verb handlers live in ``verbs_*.py`` modules and register with :func:`registry.verb`; they run in
the motion thread at a tick boundary, validate every field before acting (a rejected command
never touches the bus) and return what they applied.
"""
