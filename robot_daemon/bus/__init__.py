"""Serial transport, Dynamixel control tables, bulk read / sync write."""
