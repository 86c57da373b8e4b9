"""Example policies for `darwin policy run` (clients/learn/runner.py)."""
