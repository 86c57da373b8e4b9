"""Robot learning on the project's contract (schemas/policy.py): the policy stream client, the
Gymnasium environment (``env``, needs the ``learn`` extra), the policy runner and the LeRobot
dataset writer. docs/learning.md is the guide."""
