"""``darwin foxglove``: the robot's key space as a Foxglove WebSocket server (foxglove-sdk)."""
